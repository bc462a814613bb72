#pragma once
// Writing a file so that readers see either the old content or the complete new one, never a
// half-written file: write a temporary file beside it, fsync, then rename() over the target.

#include <filesystem>
#include <functional>
#include <ostream>
#include <string_view>

namespace hmap {

/// Calls `writer` with a stream onto a temporary file `.NAME.tmp.PID.RANDOM` in the target's
/// folder, flushes and fsyncs it, and renames it to `path` (replacing any regular file there; an
/// existing file's permission bits are kept; a device, FIFO, socket or folder is never replaced). If `writer` throws or any step fails, the temporary file is
/// removed, `path` is left as it was, and hmap::Error naming `path` is thrown.
void write_file_atomic(const std::filesystem::path& path, const std::function<void(std::ostream&)>& writer);

/// Throws hmap::Error unless `path` could be written by write_file_atomic: its folder exists and
/// is writable, and `path` is a regular file or does not exist yet. Commands call it before the
/// work, so that a missing folder is not found after mapping 80 scans.
void check_output_file(const std::filesystem::path& path);
/// Throws hmap::Error unless `dir` is an existing folder this process may create files in; the
/// message names `for_path` (the output asked for) when given.
void check_output_folder(const std::filesystem::path& dir, const std::filesystem::path& for_path = {});

/// A new, empty hidden folder beside `target` (".NAME.tmp.PID.RANDOM") to write a set of files
/// into; replace_folder_atomic then puts the whole set in place of `target` at once.
[[nodiscard]] std::filesystem::path make_staging_folder(const std::filesystem::path& target);

/// Puts the folder `staging` in place of the folder `target` in one step: rename() when `target`
/// does not exist, else renameat2(RENAME_EXCHANGE), after which the old folder (now at
/// `staging`) is removed. A kill at any moment leaves at `target` the whole old set or the whole
/// new one, never a new file beside an old one (a killed run leaves its staging folder behind).
void replace_folder_atomic(const std::filesystem::path& staging, const std::filesystem::path& target);

/// Atomically replaces `path` with `bytes`.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);

}  // namespace hmap
