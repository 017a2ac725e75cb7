#include "lshloc/fleet/redis_client.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <thread>

#include "lshloc/common/error.hpp"

namespace lshloc::fleet {

namespace {

constexpr int kMaxRedirects = 8;

/// CRC-16/XMODEM (polynomial 0x1021, initial value 0, no reflection): the
/// checksum the Redis Cluster specification names for key slots.
std::uint16_t crc16_xmodem(std::string_view bytes) {
  std::uint16_t crc = 0;
  for (const char ch : bytes) {
    crc ^= static_cast<std::uint16_t>(static_cast<std::uint8_t>(ch) << 8);
    for (int bit = 0; bit < 8; ++bit)
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021) : static_cast<std::uint16_t>(crc << 1);
  }
  return crc;
}

std::vector<std::string_view> words_of(std::span<const std::string> command) {
  return {command.begin(), command.end()};
}

/// "MOVED 3999 127.0.0.1:6381" (or ASK): the node it names; false for any
/// other error. An endpoint without a host (":6381") means the host we know.
bool redirect_target(const std::string& error, std::string_view kind, const std::string& default_host,
                     RedisAddress& to) {
  if (!error.starts_with(kind) || error.size() <= kind.size() || error[kind.size()] != ' ') return false;
  const std::size_t endpoint = error.find(' ', kind.size() + 1);
  const std::size_t colon = error.rfind(':');
  if (endpoint == std::string::npos || colon == std::string::npos || colon < endpoint)
    throw Error("a Redis redirect '" + error + "': expected " + std::string(kind) + " SLOT HOST:PORT");
  to.host = error.substr(endpoint + 1, colon - endpoint - 1);
  if (to.host.empty()) to.host = default_host;
  const std::string_view port = std::string_view(error).substr(colon + 1);
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), to.port);
  if (ec != std::errc() || end != port.data() + port.size())
    throw Error("a Redis redirect '" + error + "': expected a port after the ':'");
  return true;
}

bool is_redirect(const Reply& r) {
  return r.is_error() && (r.text.starts_with("MOVED ") || r.text.starts_with("ASK ") || r.text.starts_with("TRYAGAIN"));
}

}  // namespace

std::uint16_t hash_slot(std::string_view key) {
  const std::size_t open = key.find('{');
  if (open != std::string_view::npos) {
    const std::size_t close = key.find('}', open + 1);
    if (close != std::string_view::npos && close > open + 1) key = key.substr(open + 1, close - open - 1);
  }
  return static_cast<std::uint16_t>(crc16_xmodem(key) % 16384);
}

std::string_view routing_key(std::span<const std::string> command) {
  if (command.empty()) return {};
  std::string verb = command[0];
  std::transform(verb.begin(), verb.end(), verb.begin(), [](unsigned char c) { return std::toupper(c); });
  if (verb == "EVAL" || verb == "EVALSHA") {  // EVAL SCRIPT NUMKEYS KEY...
    return command.size() > 3 && command[2] != "0" ? std::string_view(command[3]) : std::string_view();
  }
  if (verb == "XREAD") {
    for (std::size_t i = 1; i + 1 < command.size(); ++i) {
      std::string word = command[i];
      std::transform(word.begin(), word.end(), word.begin(), [](unsigned char c) { return std::toupper(c); });
      if (word == "STREAMS") return command[i + 1];
    }
    return {};
  }
  return command.size() > 1 ? std::string_view(command[1]) : std::string_view();
}

RedisClient::RedisClient(RedisAddress seed, double timeout_s)
    : seed_(std::move(seed)), timeout_s_(timeout_s), slot_node_(std::make_unique<std::array<std::uint16_t, kSlots>>()) {
  nodes_ = {seed_};
  connections_.resize(1);
  RedisConnection& c = connection(0);
  const Reply slots = c.exchange(std::vector<std::string_view>{"CLUSTER", "SLOTS"});
  if (slots.is_error()) {
    if (slots.text.find("cluster support disabled") == std::string::npos)
      throw Error(seed_.url() + ": CLUSTER SLOTS: " + slots.text);
    return;  // one server, no cluster
  }
  cluster_ = true;
  apply_slots(slots, c.address());
}

RedisClient::~RedisClient() = default;
RedisClient::RedisClient(RedisClient&&) noexcept = default;
RedisClient& RedisClient::operator=(RedisClient&&) noexcept = default;

bool RedisClient::read_slots(RedisConnection& from) {
  const Reply r = from.exchange(std::vector<std::string_view>{"CLUSTER", "SLOTS"});
  if (r.is_error() || r.type != Reply::Type::kArray) return false;
  apply_slots(r, from.address());
  return true;
}

void RedisClient::apply_slots(const Reply& r, const RedisAddress& from) {
  ++stats_.slot_refreshes;
  slot_node_->fill(kNoNode);
  for (const Reply& range : r.elements) {
    // [first slot, last slot, [host, port, id, ...] of the master, replicas...]
    if (range.elements.size() < 3 || range.elements[2].elements.size() < 2)
      throw Error(from.url() + ": CLUSTER SLOTS: expected [first, last, [host, port, ...], ...] per range");
    const long long first = range.elements[0].integer, last = range.elements[1].integer;
    if (first < 0 || last >= static_cast<long long>(kSlots) || first > last)
      throw Error(from.url() + ": CLUSTER SLOTS: a slot range " + std::to_string(first) + ".." + std::to_string(last) +
                  " outside 0..16383");
    const Reply& master = range.elements[2];
    RedisAddress a;
    a.host = master.elements[0].text.empty() || master.elements[0].text == "?" ? from.host : master.elements[0].text;
    a.port = static_cast<int>(master.elements[1].integer);
    const auto node = static_cast<std::uint16_t>(node_index(a));
    std::fill(slot_node_->begin() + first, slot_node_->begin() + last + 1, node);
  }
}

std::size_t RedisClient::node_index(const RedisAddress& a) {
  for (std::size_t i = 0; i < nodes_.size(); ++i)
    if (nodes_[i].host == a.host && nodes_[i].port == a.port) return i;
  nodes_.push_back(a);
  connections_.emplace_back();
  return nodes_.size() - 1;
}

RedisConnection& RedisClient::connection(std::size_t node) {
  if (!connections_[node]) connections_[node] = std::make_unique<RedisConnection>(nodes_[node], timeout_s_);
  return *connections_[node];
}

std::size_t RedisClient::node_of_slot(std::uint16_t slot) const {
  const std::uint16_t node = (*slot_node_)[slot];
  if (node == kNoNode)
    throw Error(seed_.url() + ": hash slot " + std::to_string(slot) +
                " is served by no node of the cluster (is every slot assigned?)");
  return node;
}

std::size_t RedisClient::node_of(std::string_view key) const {
  if (!cluster_ || key.empty()) return 0;
  return node_of_slot(hash_slot(key));
}

Reply RedisClient::run(std::vector<std::string> command) {
  std::size_t node = node_of(routing_key(command));
  bool asking = false;
  for (int hop = 0; hop <= kMaxRedirects; ++hop) {
    RedisConnection& c = connection(node);
    Reply r = asking ? c.exchange_all({{"ASKING"}, command}).back() : c.exchange(words_of(command));
    asking = false;
    if (!cluster_ || !r.is_error()) return r;
    RedisAddress to;
    if (redirect_target(r.text, "MOVED", nodes_[node].host, to)) {
      // The slot moved for good: learn the new table, and go where the server said.
      ++stats_.moved;
      node = node_index(to);
      read_slots(connection(node));
    } else if (redirect_target(r.text, "ASK", nodes_[node].host, to)) {
      // The slot is migrating and this key has gone ahead: ask there, once.
      ++stats_.asked;
      node = node_index(to);
      asking = true;
    } else if (r.text.starts_with("TRYAGAIN")) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    } else {
      return r;
    }
  }
  throw Error(seed_.url() + ": " + command.front() + ": more than " + std::to_string(kMaxRedirects) +
              " cluster redirects");
}

Reply RedisClient::command(std::span<const std::string_view> args) {
  Reply r = run(std::vector<std::string>(args.begin(), args.end()));
  if (r.is_error()) throw Error(seed_.url() + ": " + (args.empty() ? "" : std::string(args[0])) + ": " + r.text);
  return r;
}

std::vector<Reply> RedisClient::pipeline(const std::vector<std::vector<std::string>>& commands) {
  std::vector<Reply> replies(commands.size());
  if (!cluster_) {
    replies = connection(0).exchange_all(commands);
  } else {
    std::vector<std::vector<std::size_t>> share(nodes_.size());
    for (std::size_t i = 0; i < commands.size(); ++i) share[node_of(routing_key(commands[i]))].push_back(i);
    for (std::size_t node = 0; node < share.size(); ++node) {
      if (share[node].empty()) continue;
      std::vector<std::vector<std::string>> mine;
      mine.reserve(share[node].size());
      for (const std::size_t i : share[node]) mine.push_back(commands[i]);
      std::vector<Reply> got = connection(node).exchange_all(mine);
      for (std::size_t k = 0; k < got.size(); ++k) replies[share[node][k]] = std::move(got[k]);
    }
    // A redirected command did not run: run it where it belongs, in order.
    // Commands on one key keep theirs: once one was redirected, every later
    // one on that key was too (the key had moved, or gone ahead in a migration).
    for (std::size_t i = 0; i < commands.size(); ++i)
      if (is_redirect(replies[i])) replies[i] = run(commands[i]);
  }
  for (std::size_t i = 0; i < replies.size(); ++i)
    if (replies[i].is_error()) throw Error(seed_.url() + ": " + commands[i].front() + ": " + replies[i].text);
  return replies;
}

void RedisClient::reconnect() {
  for (auto& c : connections_) c.reset();
  std::string why;
  for (std::size_t node = 0; node < nodes_.size(); ++node) {
    try {
      RedisConnection& c = connection(node);
      if (!cluster_ || read_slots(c)) return;
    } catch (const Error& e) {
      why = e.what();
    }
    if (!cluster_) break;
  }
  throw Error(seed_.url() + ": cannot reconnect: " + (why.empty() ? "no node answered CLUSTER SLOTS" : why));
}

}  // namespace lshloc::fleet
