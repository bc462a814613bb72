#include "hmap/io/atomic_file.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include "io/io_test_util.hpp"

namespace hmap {
namespace {

using test::contains;
using test::input_error_of;  // hmap::Error too: "<not an InputError: MESSAGE>"

class AtomicFileTest : public test::IoTest {
 protected:
  [[nodiscard]] std::string read(const std::filesystem::path& path) const {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    return text.str();
  }
  [[nodiscard]] std::size_t files_in_dir() const {
    std::size_t count = 0;
    for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir_)) ++count;
    return count;
  }
};

TEST_F(AtomicFileTest, WritesNewFile) {
  const auto path = dir_ / "new.txt";
  write_file_atomic(path, [](std::ostream& out) { out << "hello " << 42 << '\n'; });
  EXPECT_EQ(read(path), "hello 42\n");
  EXPECT_EQ(files_in_dir(), 1U);
}

TEST_F(AtomicFileTest, ReplacesExistingFileAndKeepsItsMode) {
  const auto path = write("old.txt", "old content that is longer than the new one");
  ::chmod(path.c_str(), 0640);
  write_file_atomic(path, std::string_view("new"));
  EXPECT_EQ(read(path), "new");
  struct stat info {};
  ASSERT_EQ(::stat(path.c_str(), &info), 0);
  EXPECT_EQ(info.st_mode & 0777, 0640U);
  EXPECT_EQ(files_in_dir(), 1U);
}

TEST_F(AtomicFileTest, WritesLargeContent) {
  std::string big(3'000'000, 'x');
  for (std::size_t i = 0; i < big.size(); i += 7) big[i] = static_cast<char>('a' + i % 26);
  const auto path = dir_ / "big.bin";
  write_file_atomic(path, [&](std::ostream& out) {
    out.write(big.data(), 10);  // small write through the buffer, then a large one past it
    out.write(big.data() + 10, static_cast<std::streamsize>(big.size() - 10));
  });
  EXPECT_EQ(read(path), big);
}

TEST_F(AtomicFileTest, ThrowingWriterLeavesOldFileAndNoTemporary) {
  const auto path = write("keep.txt", "precious");
  try {
    write_file_atomic(path, [](std::ostream& out) {
      out << std::string(100000, 'y');  // some of it already on disk in the temporary file
      throw std::runtime_error("writer failed");
    });
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), path.string()));
    EXPECT_TRUE(contains(e.what(), "writer failed"));
  }
  EXPECT_EQ(read(path), "precious");
  EXPECT_EQ(files_in_dir(), 1U);
}

TEST_F(AtomicFileTest, HmapErrorsFromTheWriterNameThePath) {
  const auto path = dir_ / "p.txt";
  try {
    write_file_atomic(path, [](std::ostream&) { throw Error("pose 3 is not finite"); });
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path.string() + ": pose 3 is not finite");
  }
  EXPECT_EQ(files_in_dir(), 0U);
}

TEST_F(AtomicFileTest, FailsInMissingFolder) {
  const auto path = dir_ / "no" / "such" / "dir.txt";
  try {
    write_file_atomic(path, std::string_view("x"));
    FAIL() << "no exception";
  } catch (const Error& e) {
    EXPECT_TRUE(contains(e.what(), path.string()));
    EXPECT_TRUE(contains(e.what(), "No such file or directory"));
  }
}

TEST_F(AtomicFileTest, NeverReplacesWhatIsNotARegularFile) {
  const auto fifo = dir_ / "f.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  std::filesystem::create_directory(dir_ / "d");
  for (const auto& target : {fifo, dir_ / "d"}) {
    EXPECT_TRUE(contains(input_error_of([&] { write_file_atomic(target, std::string_view("x")); }),
                         "not a regular file: refusing to replace it"));
    EXPECT_TRUE(contains(input_error_of([&] { check_output_file(target); }), "not a regular file"));
  }
  struct stat st {};
  ASSERT_EQ(::stat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode));
  EXPECT_EQ(files_in_dir(), 2U);  // no temporary left
  EXPECT_TRUE(contains(input_error_of([&] { check_output_file(dir_ / "none" / "m.hmap"); }),
                       "the output folder " + (dir_ / "none").string() + " does not exist"));
  EXPECT_NO_THROW(check_output_file(dir_ / "new.hmap"));
}

TEST_F(AtomicFileTest, AFolderIsReplacedAsAWhole) {
  const auto target = dir_ / "set";
  // New folder: renamed into place.
  auto staging = make_staging_folder(target);
  write_file_atomic(staging / "a.txt", std::string_view("1"));
  replace_folder_atomic(staging, target);
  EXPECT_EQ(read(target / "a.txt"), "1");
  // Over an old one: exchanged, the old set gone with its file the new set lacks.
  std::ofstream(target / "old_only.txt") << "old";
  staging = make_staging_folder(target);
  EXPECT_TRUE(staging.filename().string().starts_with(".set.tmp."));
  write_file_atomic(staging / "a.txt", std::string_view("2"));
  replace_folder_atomic(staging, target);
  EXPECT_EQ(read(target / "a.txt"), "2");
  EXPECT_FALSE(std::filesystem::exists(target / "old_only.txt"));
  EXPECT_FALSE(std::filesystem::exists(staging));
  EXPECT_EQ(files_in_dir(), 1U);
}

/// The PID of a process that has ended (a child reaped here).
pid_t ended_pid() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return child;
}

// What a killed run left beside its output goes with the next write there: the temporaries of
// ended processes untouched for kStaleTemporaryAge. A fresh one (its writer may be in another PID
// namespace), one of this process, and other names stay.
TEST_F(AtomicFileTest, LeftoversOfKilledRunsAreRemovedByTheNextWrite) {
  const std::string dead = std::to_string(ended_pid());
  const std::string alive = std::to_string(::getpid());
  const auto old = std::filesystem::file_time_type::clock::now() - kStaleTemporaryAge - std::chrono::minutes(1);
  const auto make = [&](const std::string& name, bool folder, bool aged) {
    const auto path = dir_ / name;
    if (folder) {
      std::filesystem::create_directory(path);
      std::ofstream(path / "poses.txt") << "half";
    } else {
      std::ofstream(path) << "half";
    }
    if (aged) std::filesystem::last_write_time(path, old);
    return path;
  };
  const auto stale_folder = make(".set.tmp." + dead + ".0badc0de", true, true);
  const auto stale_file = make(".m.hmap.tmp." + dead + ".12345678", false, true);
  const auto fresh = make(".set.tmp." + dead + ".aaaaaaaa", true, false);
  const auto ours = make(".set.tmp." + alive + ".bbbbbbbb", true, true);
  const auto other_name = make(".sets.tmp." + dead + ".cccccccc", true, true);
  const auto not_ours = make(".set.tmp.12x4.dddddddd", false, true);
  const auto not_hex = make(".set.tmp." + dead + ".notahexx", false, true);

  write_folder_atomic(dir_ / "set", [](const std::filesystem::path& d) { write_file_atomic(d / "a.txt", std::string_view("1")); });
  EXPECT_FALSE(std::filesystem::exists(stale_folder));
  for (const auto& kept : {fresh, ours, other_name, not_ours, not_hex}) EXPECT_TRUE(std::filesystem::exists(kept)) << kept;
  EXPECT_TRUE(std::filesystem::exists(stale_file)) << "another target's leftovers wait for a write to it";

  write_file_atomic(dir_ / "m.hmap", std::string_view("map"));
  EXPECT_FALSE(std::filesystem::exists(stale_file));
  EXPECT_EQ(read(dir_ / "m.hmap"), "map");
  EXPECT_EQ(read(dir_ / "set" / "a.txt"), "1");
}

}  // namespace
}  // namespace hmap
