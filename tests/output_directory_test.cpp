// io::require_writable_directory: the check a long run makes on an output
// directory before it starts.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "lshloc/common/error.hpp"
#include "lshloc/io/atomic_file.hpp"
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

}  // namespace
}  // namespace lshloc
