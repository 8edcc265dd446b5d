// formats/durable_file.h: appends reach the file at once and in order, a replaced file is the
// old or the new content and never a temporary, and errors name the file.
#include "formats/durable_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>

#include "tests/test_util/temp_dir.h"

namespace echoservo::formats {
namespace {

namespace fs = std::filesystem;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

TEST(AppendOnlyFile, EachAppendIsInTheFileWhenItReturns) {
  const testing::TempDir dir("durable", true);
  const fs::path p = dir.path() / "a.bin";
  { std::ofstream(p) << "old content that must go"; }
  AppendOnlyFile f(p);
  EXPECT_TRUE(f.is_open());
  EXPECT_EQ(Slurp(p), "");  // truncated
  f.Append("one,");
  EXPECT_EQ(Slurp(p), "one,");  // no user-space buffer
  const unsigned char bytes[] = {0, 1, 2, 255};
  f.Append(bytes, sizeof bytes);
  f.SyncData();
  EXPECT_EQ(Slurp(p), std::string("one,") + std::string("\0\1\2\xff", 4));
  AppendOnlyFile moved = std::move(f);
  EXPECT_FALSE(f.is_open());  // NOLINT(bugprone-use-after-move): the moved-from state is specified
  moved.Append("two");
  EXPECT_EQ(Slurp(p).substr(8), "two");
  EXPECT_THROW(f.Append("x"), std::logic_error);
}

TEST(AppendOnlyFile, ErrorsNameTheFile) {
  const testing::TempDir dir("durable_err", true);
  try {
    AppendOnlyFile f(dir.path() / "no" / "such.bin");
    FAIL() << "opened a file in a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no/such.bin"), std::string::npos) << e.what();
  }
}

TEST(ReplaceFileContents, ReplacesWholeAndLeavesNoTemporary) {
  const testing::TempDir dir("durable_replace", true);
  const fs::path p = dir.path() / "h.txt";
  ReplaceFileContents(p, "first version, longer than the second\n");
  EXPECT_EQ(Slurp(p), "first version, longer than the second\n");
  ReplaceFileContents(p, "second\n");
  EXPECT_EQ(Slurp(p), "second\n");
  EXPECT_FALSE(fs::exists(dir.path() / "h.txt.tmp"));
  EXPECT_THROW(ReplaceFileContents(dir.path() / "no" / "h.txt", "x"), std::runtime_error);
  EXPECT_EQ(Slurp(p), "second\n");
}

}  // namespace
}  // namespace echoservo::formats
