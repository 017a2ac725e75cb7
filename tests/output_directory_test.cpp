// io::require_writable_directory: the check a long run makes on an output
// directory before it starts; outputs that name a FIFO or a device.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>

#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"
#include "lshloc/io/map_store.hpp"
#include "test_support.hpp"

namespace lshloc {
namespace {

TEST(OutputDirectory, MissingParentsAreCreated) {
  const std::string dir = test::temp_path("-out") + "/a/b";
  io::require_writable_directory(dir);
  EXPECT_TRUE(std::filesystem::is_directory(dir));
  io::require_writable_directory(dir);  // existing: fine
}

TEST(OutputDirectory, ADirectoryUnderAFileIsRefusedNamingItAndItsPurpose) {
  const std::string file = test::temp_path("-file");
  test::write_file(file, "x");
  try {
    io::require_writable_directory(file + "/traces", "the trace directory");
    FAIL() << "a directory under a file was accepted";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(file + "/traces: cannot create the trace directory"), std::string::npos) << what;
  }
}

TEST(OutputFiles, AFifoIsWrittenIntoNeverReplaced) {
  // A FIFO stands for a device such as /dev/null (which a test must not risk): written into, still a FIFO.
  const std::string fifo = test::temp_path(".fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] {
    std::ifstream in(fifo);
    received.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  });
  io::require_writable(fifo);
  io::write_file_atomically(fifo, "one run's output\n");
  reader.join();
  EXPECT_EQ(received, "one run's output\n");
  EXPECT_TRUE(std::filesystem::is_fifo(fifo));
  // A saved map is replaced whole: a FIFO (or a device) is refused, and stays.
  try {
    io::replace_file(fifo, {});
    ADD_FAILURE() << "a FIFO was replaced";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is a character device or FIFO"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(std::filesystem::is_fifo(fifo));
  // ... and so before the run that would make it (map build, map from-redis, eval --save-map).
  try {
    io::require_replaceable(fifo);
    ADD_FAILURE() << "a FIFO passed as a map's output";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is a character device or FIFO"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(io::require_replaceable(test::temp_path(".map")));
  // Read as a map, a FIFO with no writer is refused at once, not waited on.
  try {
    io::load_map(fifo);
    ADD_FAILURE() << "a FIFO loaded as a map";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  std::filesystem::remove(fifo);
  // A directory is no output.
  EXPECT_THROW(io::write_file_atomically(std::filesystem::temp_directory_path().string(), "x"), Error);
}

}  // namespace
}  // namespace lshloc
