#include "lshloc/io/ros_map.hpp"

#include <png.h>
#include <yaml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>
#include <vector>

#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"

namespace lshloc::io {

namespace {
// map_server's trinary convention: p = (255 - value) / 255 against the thresholds.
constexpr unsigned char kOccupiedGrey = 0, kFreeGrey = 254, kUnknownGrey = 205;
}  // namespace

void write_ros_map(const std::string& stem, const OccupancyGrid& grid) {
  const std::string pgm = stem + ".pgm", yaml = stem + ".yaml";
  std::ostringstream image(std::ios::binary);
  image << "P5\n# lshloc occupancy grid, " << grid.resolution << " m/cell\n"
        << grid.width << ' ' << grid.height << "\n255\n";
  std::string row(grid.width, '\0');
  for (std::size_t r = grid.height; r-- > 0;) {
    for (std::size_t c = 0; c < grid.width; ++c) {
      const std::int8_t v = grid.at(c, r);
      row[c] = static_cast<char>(v == occupancy::kOccupied ? kOccupiedGrey
                                 : v == occupancy::kFree   ? kFreeGrey
                                                           : kUnknownGrey);
    }
    image << row;
  }
  const std::string image_bytes = image.str();
  // Numbers in their shortest exact form (UTM origins keep their millimetres); the
  // image's name double-quoted (a '#' or ': ' in it would otherwise be YAML syntax).
  const auto exact = [](double v) {
    char buf[32];
    const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v);
    return std::string(buf, ec == std::errc() ? end : buf);
  };
  std::string name = "\"";
  for (const char c : std::filesystem::path(pgm).filename().string()) {
    if (c == '"' || c == '\\') {
      name += '\\', name += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02X", static_cast<unsigned>(static_cast<unsigned char>(c)));
      name += hex;
    } else {
      name += c;
    }
  }
  name += '"';
  const std::string yaml_bytes = "image: " + name + "\nmode: trinary\nresolution: " + exact(grid.resolution) +
                                 "\norigin: [" + exact(grid.origin.x()) + ", " + exact(grid.origin.y()) + ", " +
                                 exact(grid.origin_yaw) + "]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  // Together: an image beside the YAML of another map would be a silently wrong map.
  const FileOutput files[] = {{pgm, image_bytes}, {yaml, yaml_bytes}};
  write_files_atomically(files);
}

namespace {

/// A YAML value: a scalar's text or a flow/block sequence of scalars, with
/// the line it stands on (1-based) for messages.
struct YamlValue {
  std::string scalar;
  std::vector<std::string> items;
  bool is_sequence = false;
  bool nested = false;  ///< a mapping, or a sequence holding more than scalars: other tools' settings
  std::size_t line = 0;
};

/// The bytes of the regular file at `path` (`what` names it in messages).
std::string read_regular_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw FileError(path + ": " + what + " is not a regular file (a directory?)");
  // Larger than any image of the grid's cell cap (2^28 cells, two bytes each) or any YAML: a wrong file.
  constexpr std::uintmax_t kMaxBytes = std::uintmax_t{1} << 30;
  if (const auto bytes = std::filesystem::file_size(path, ec); !ec && bytes > kMaxBytes)
    throw Error(path + ": " + what + " has " + std::to_string(bytes) + " bytes, over the cap of " +
                std::to_string(kMaxBytes));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FileError(path + ": cannot open " + what + ": " + std::strerror(errno));
  std::string data;
  try {  // a read error (a /proc file) surfaces as an exception from the stream buffer
    data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  } catch (const std::exception& e) {
    throw FileError(path + ": cannot read " + what + ": " + e.what());
  }
  if (in.bad()) throw FileError(path + ": cannot read " + what);
  if (data.size() > kMaxBytes)
    throw Error(path + ": " + what + " holds more than " + std::to_string(kMaxBytes) + " bytes");
  return data;
}

/// The top-level mapping of a map_server YAML file, key -> value.
std::map<std::string, YamlValue> read_yaml_mapping(const std::string& path) {
  const std::string text = read_regular_file(path, "the map YAML");
  // A few lines: the cap also bounds the parser's time on deeply nested junk.
  if (text.size() > (1u << 16))
    throw Error(path + ": expected a map_server YAML of a few lines, got " + std::to_string(text.size()) + " bytes");
  yaml_parser_t parser;
  if (!yaml_parser_initialize(&parser)) throw Error(path + ": cannot start the YAML parser");
  const std::unique_ptr<yaml_parser_t, void (*)(yaml_parser_t*)> parser_guard(&parser, yaml_parser_delete);
  yaml_parser_set_input_string(&parser, reinterpret_cast<const unsigned char*>(text.data()), text.size());
  yaml_document_t doc;
  if (!yaml_parser_load(&parser, &doc)) {
    throw Error(path + ":" + std::to_string(parser.problem_mark.line + 1) +
                ": invalid YAML: " + (parser.problem ? parser.problem : "parse error"));
  }
  const std::unique_ptr<yaml_document_t, void (*)(yaml_document_t*)> doc_guard(&doc, yaml_document_delete);
  const yaml_node_t* root = yaml_document_get_root_node(&doc);
  if (root == nullptr || root->type != YAML_MAPPING_NODE)
    throw Error(path + ": expected a YAML mapping (image, resolution, origin, ...)");
  const auto scalar = [](const yaml_node_t* n) {
    return std::string(reinterpret_cast<const char*>(n->data.scalar.value), n->data.scalar.length);
  };
  std::map<std::string, YamlValue> out;
  for (const yaml_node_pair_t* pair = root->data.mapping.pairs.start; pair < root->data.mapping.pairs.top; ++pair) {
    const yaml_node_t* key = yaml_document_get_node(&doc, pair->key);
    const yaml_node_t* value = yaml_document_get_node(&doc, pair->value);
    const std::string where = path + ":" + std::to_string(key->start_mark.line + 1);
    if (key->type != YAML_SCALAR_NODE) throw Error(where + ": expected a plain key");
    YamlValue v;
    v.line = value->start_mark.line + 1;
    if (value->type == YAML_SCALAR_NODE) {
      v.scalar = scalar(value);
    } else if (value->type == YAML_SEQUENCE_NODE) {
      v.is_sequence = true;
      for (const yaml_node_item_t* item = value->data.sequence.items.start; item < value->data.sequence.items.top;
           ++item) {
        const yaml_node_t* n = yaml_document_get_node(&doc, *item);
        if (n->type != YAML_SCALAR_NODE) {
          v.nested = true;
          break;
        }
        v.items.push_back(scalar(n));
      }
    } else {
      v.nested = true;  // a mapping: other tools' settings (e.g. nav2's parameters), unless it is a key we read
    }
    if (!out.emplace(scalar(key), v).second) throw Error(where + ": key " + scalar(key) + " given twice");
  }
  return out;
}

/// Edits (insert, delete, replace one character) that make `a` into `b`.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// Refuses a key a letter or two off one map_server reads: map_server would
/// ignore it, and the map take a default the user meant to change.
void refuse_misspelt_keys(const std::map<std::string, YamlValue>& yaml, const std::string& path) {
  static constexpr std::array<const char*, 7> kKeys = {"image",           "resolution",  "origin", "negate",
                                                       "occupied_thresh", "free_thresh", "mode"};
  for (const auto& [key, value] : yaml) {
    if (std::find(kKeys.begin(), kKeys.end(), key) != kKeys.end()) continue;
    for (const char* known : kKeys)
      if (edit_distance(key, known) <= (std::strlen(known) >= 6 ? 2u : 1u))
        throw Error(path + ":" + std::to_string(value.line) + ": unknown key '" + key + "'; expected '" + known +
                    "' (map_server would ignore it and take the default)");
  }
}

double parse_number(const std::string& text, const std::string& where, const std::string& key) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE || !std::isfinite(v))
    throw Error(where + ": " + key + ": expected a finite number, got '" + text + "'");
  return v;
}

/// A map image (PGM binary P5 or plain P2, or PNG) with its grey values as stored.
struct GreyImage {
  std::size_t width = 0, height = 0;
  std::size_t maxval = 255;
  std::vector<std::uint16_t> pixels;  // row-major, row 0 at the top
};

/// An 8-bit PNG (grey, colour or palette; alpha ignored, as map_server's
/// trinary and raw modes do): a colour pixel's value is the sum of its
/// channels over a maximum of 765, so that p is map_server's channel average.
GreyImage read_png(const std::string& path, const std::string& data) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  const std::unique_ptr<png_image, void (*)(png_image*)> done(&png, png_image_free);
  if (!png_image_begin_read_from_memory(&png, data.data(), data.size()))
    throw Error(path + ": " + png.message + "; expected a PNG image");
  // 16-bit samples come out gamma-converted from the simplified API: refused rather than thresholded off.
  if (png.format & PNG_FORMAT_FLAG_LINEAR)
    throw Error(path + ": a 16-bit PNG; expected 8 bits per sample (or a 16-bit PGM: `convert map.png map.pgm`)");
  if (static_cast<double>(png.width) * static_cast<double>(png.height) > static_cast<double>(1u << 28))
    throw Error(path + ": " + std::to_string(png.width) + " x " + std::to_string(png.height) + " pixels exceed 2^28");
  const bool colour = (png.format & PNG_FORMAT_FLAG_COLOR) != 0;
  png.format = colour ? PNG_FORMAT_RGBA : PNG_FORMAT_GA;
  const std::size_t channels = colour ? 4 : 2;
  std::vector<std::uint8_t> samples(PNG_IMAGE_SIZE(png));
  if (!png_image_finish_read(&png, nullptr, samples.data(), 0, nullptr))
    throw Error(path + ": " + png.message + "; expected a whole PNG image");
  GreyImage img;
  img.width = png.width, img.height = png.height;
  img.maxval = colour ? 765 : 255;
  img.pixels.resize(img.width * img.height);
  for (std::size_t i = 0; i < img.pixels.size(); ++i) {
    const std::uint8_t* s = &samples[i * channels];
    img.pixels[i] = static_cast<std::uint16_t>(colour ? s[0] + s[1] + s[2] : s[0]);
  }
  return img;
}

/// The map image: a PGM, or a PNG by its signature.
GreyImage read_map_image(const std::string& path) {
  const std::string data = read_regular_file(path, "the map image");
  if (data.size() >= 8 && data.compare(0, 8, "\x89PNG\r\n\x1a\n") == 0) return read_png(path, data);
  std::size_t pos = 0;
  const auto skip_space = [&] {
    while (pos < data.size()) {
      if (data[pos] == '#') {
        while (pos < data.size() && data[pos] != '\n') ++pos;
      } else if (std::isspace(static_cast<unsigned char>(data[pos]))) {
        ++pos;
      } else {
        break;
      }
    }
  };
  const auto header_number = [&](const char* what) {
    skip_space();
    std::size_t v = 0, digits = 0;
    while (pos < data.size() && std::isdigit(static_cast<unsigned char>(data[pos])) && digits < 9)
      v = v * 10 + static_cast<std::size_t>(data[pos++] - '0'), ++digits;
    if (digits == 0 || (pos < data.size() && std::isdigit(static_cast<unsigned char>(data[pos]))))
      throw Error(path + ": byte " + std::to_string(pos) + ": expected the PGM " + what + " (a number below 1e9)");
    return v;
  };
  if (data.size() < 2 || data[0] != 'P' || (data[1] != '5' && data[1] != '2'))
    throw Error(path + ": expected a PGM image (P5 binary or P2 plain greyscale) or an 8-bit PNG");
  const bool binary = data[1] == '5';
  pos = 2;
  GreyImage img;
  img.width = header_number("width");
  img.height = header_number("height");
  const std::size_t maxval = header_number("maximum grey value");
  if (img.width == 0 || img.height == 0 || maxval == 0 || maxval > 65535)
    throw Error(path + ": expected a positive width and height and a maximum grey value in 1..65535");
  if (static_cast<double>(img.width) * static_cast<double>(img.height) > static_cast<double>(1u << 28))
    throw Error(path + ": " + std::to_string(img.width) + " x " + std::to_string(img.height) + " pixels exceed 2^28");
  const std::size_t n = img.width * img.height;
  // Checked before allocating: a short file cannot make the header reserve 2^28 pixels.
  const std::size_t left = data.size() > pos ? data.size() - pos : 0;
  if (!binary && left < 2 * n - 1)
    throw Error(path + ": expected " + std::to_string(n) + " plain pixel values after the header, but only " +
                std::to_string(left) + " bytes follow");
  img.pixels.resize(n);
  img.maxval = maxval;
  if (binary) {
    // Exactly one whitespace byte after maxval, then the raster: a header line
    // ending in CR LF would make the LF the first pixel and shift the map.
    if (pos >= data.size() || !std::isspace(static_cast<unsigned char>(data[pos])))
      throw Error(path + ": byte " + std::to_string(pos) +
                  ": expected one whitespace byte between the maximum grey value and the pixels");
    if (data[pos] == '\r' && pos + 1 < data.size() && data[pos + 1] == '\n')
      throw Error(path +
                  ": the PGM header ends in CR LF: expected one whitespace byte before the pixels (the LF "
                  "would be read as the first pixel)");
    ++pos;
    const std::size_t bytes = maxval > 255 ? 2 : 1;
    if (data.size() < pos + n * bytes)
      throw Error(path + ": expected " + std::to_string(n * bytes) + " bytes of pixels after the header, got " +
                  std::to_string(data.size() > pos ? data.size() - pos : 0));
    // More than whitespace after the raster: the header's width or height is likely wrong.
    for (std::size_t i = pos + n * bytes; i < data.size(); ++i)
      if (!std::isspace(static_cast<unsigned char>(data[i])))
        throw Error(path + ": " + std::to_string(data.size() - pos - n * bytes) + " bytes follow the " +
                    std::to_string(img.width) + " x " + std::to_string(img.height) +
                    " pixels; expected the image to end there (are its width and height right?)");
    for (std::size_t i = 0; i < n; ++i) {
      std::size_t v = static_cast<unsigned char>(data[pos + i * bytes]);
      if (bytes == 2) v = v << 8 | static_cast<unsigned char>(data[pos + i * bytes + 1]);
      if (v > maxval) throw Error(path + ": pixel " + std::to_string(i) + " exceeds the maximum grey value");
      img.pixels[i] = static_cast<std::uint16_t>(v);
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t v = header_number("pixel value");
      if (v > maxval) throw Error(path + ": pixel " + std::to_string(i) + " exceeds the maximum grey value");
      img.pixels[i] = static_cast<std::uint16_t>(v);
    }
  }
  return img;
}

}  // namespace

bool is_ros_map_path(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".yaml" || ext == ".yml";
}

OccupancyGrid read_ros_map(const std::string& yaml_path) {
  const std::map<std::string, YamlValue> yaml = read_yaml_mapping(yaml_path);
  refuse_misspelt_keys(yaml, yaml_path);
  const auto get = [&](const std::string& key, bool required) -> const YamlValue* {
    const auto it = yaml.find(key);
    if (it == yaml.end()) {
      if (required) throw Error(yaml_path + ": expected the key '" + key + "' (map_server's map YAML)");
      return nullptr;
    }
    if (it->second.nested)
      throw Error(yaml_path + ":" + std::to_string(it->second.line) + ": " + key +
                  ": expected a value or a list of numbers (as map_server writes it), got nested values");
    return &it->second;
  };
  const auto where = [&](const YamlValue& v) { return yaml_path + ":" + std::to_string(v.line); };
  const auto number = [&](const std::string& key, double fallback) {
    const YamlValue* v = get(key, false);
    if (v == nullptr) return fallback;
    if (v->is_sequence) throw Error(where(*v) + ": " + key + ": expected a number, got a list");
    return parse_number(v->scalar, where(*v), key);
  };

  const YamlValue& image = *get("image", true);
  if (image.is_sequence || image.scalar.empty()) throw Error(where(image) + ": image: expected a file name");
  OccupancyGrid grid;
  const YamlValue& resolution = *get("resolution", true);
  grid.resolution = number("resolution", 0.0);
  if (!(grid.resolution > 0.0)) throw Error(where(resolution) + ": resolution: expected > 0 m per cell");
  const YamlValue& origin = *get("origin", true);
  if (!origin.is_sequence || origin.items.size() != 3) throw Error(where(origin) + ": origin: expected [x, y, yaw]");
  grid.origin = {parse_number(origin.items[0], where(origin), "origin x"),
                 parse_number(origin.items[1], where(origin), "origin y")};
  grid.origin_yaw = parse_number(origin.items[2], where(origin), "origin yaw");
  double negate = 0.0;  // 0 or 1, or (as nav2 also reads it) false or true
  if (const YamlValue* n = get("negate", false)) {
    if (!n->is_sequence && (n->scalar == "true" || n->scalar == "false"))
      negate = n->scalar == "true" ? 1.0 : 0.0;
    else
      negate = number("negate", 0.0);
    if (negate != 0.0 && negate != 1.0) throw Error(where(*n) + ": negate: expected 0 or 1 (or false or true)");
  }
  const double occupied_thresh = number("occupied_thresh", 0.65), free_thresh = number("free_thresh", 0.196);
  if (!(free_thresh >= 0.0 && free_thresh <= occupied_thresh && occupied_thresh <= 1.0))
    throw Error(yaml_path + ": expected 0 <= free_thresh <= occupied_thresh <= 1, got " + std::to_string(free_thresh) +
                " and " + std::to_string(occupied_thresh));
  std::string mode = "trinary";
  if (const YamlValue* m = get("mode", false)) {
    mode = m->scalar;
    if (mode != "trinary" && mode != "scale" && mode != "raw")
      throw Error(where(*m) + ": mode: expected trinary, scale or raw, got '" + mode + "'");
  }

  std::filesystem::path image_path(image.scalar);
  if (image_path.is_relative()) image_path = std::filesystem::path(yaml_path).parent_path() / image_path;
  // Image errors also name the YAML's line that points at the image.
  GreyImage img;
  try {
    img = read_map_image(image_path.string());
  } catch (const FileError& e) {
    throw FileError(where(image) + ": image: " + e.what());
  } catch (const Error& e) {
    throw Error(where(image) + ": image: " + e.what());
  }
  grid.width = img.width, grid.height = img.height;
  grid.cells.assign(img.width * img.height, occupancy::kUnknown);
  for (std::size_t r = 0; r < img.height; ++r) {
    // The image's top row is the grid's highest y.
    const std::uint16_t* row = &img.pixels[(img.height - 1 - r) * img.width];
    const double maxval = static_cast<double>(img.maxval);
    for (std::size_t c = 0; c < img.width; ++c) {
      std::int8_t& cell = grid.cells[r * img.width + c];
      if (mode == "raw") {  // the grey value read as 0..100 occupancy, on a 0..255 scale
        const double v =
            img.maxval == 255 ? row[c] : std::floor((static_cast<double>(row[c]) * 255.0 + maxval / 2) / maxval);
        if (v <= 100)
          cell = v / 100.0 > occupied_thresh ? occupancy::kOccupied
                 : v / 100.0 < free_thresh   ? occupancy::kFree
                                             : occupancy::kUnknown;
        continue;
      }
      // p from the value as stored (a 16-bit image is not rounded to 8 bits first).
      const double v = row[c];
      const double p = negate != 0.0 ? v / maxval : (maxval - v) / maxval;
      cell = p > occupied_thresh ? occupancy::kOccupied : p < free_thresh ? occupancy::kFree : occupancy::kUnknown;
    }
  }
  return grid;
}

}  // namespace lshloc::io
