#pragma once
// Writing a file so that readers see either the old content or the complete new one, never a
// half-written file: write a temporary file beside it, fsync, then rename() over the target.

#include <chrono>
#include <filesystem>
#include <functional>
#include <initializer_list>
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

/// How long a temporary file or staging folder of a process that no longer runs is left alone
/// before remove_stale_temporaries takes it away (a process in another PID namespace writing into
/// the same folder is not visible to kill(); none writes a temporary for this long untouched).
inline constexpr std::chrono::minutes kStaleTemporaryAge{5};

/// Removes what killed runs left beside `target`: the temporary files and staging folders
/// `.NAME.tmp.PID.RANDOM` (NAME the target's file name) whose PID no longer runs and which were
/// not modified for kStaleTemporaryAge. Best effort: what cannot be removed stays. Every atomic
/// write here calls it for its target first, so a killed run's leftovers go with the next run.
void remove_stale_temporaries(const std::filesystem::path& target);

/// A new, empty hidden folder beside `target` (".NAME.tmp.PID.RANDOM") to write a set of files
/// into; replace_folder_atomic then puts the whole set in place of `target` at once.
[[nodiscard]] std::filesystem::path make_staging_folder(const std::filesystem::path& target);

/// Puts the folder `staging` in place of the folder `target` in one step: rename() when `target`
/// does not exist, else renameat2(RENAME_EXCHANGE), after which the old folder (now at
/// `staging`) is removed. A kill at any moment leaves at `target` the whole old set or the whole
/// new one, never a new file beside an old one (a killed run leaves its staging folder behind).
void replace_folder_atomic(const std::filesystem::path& staging, const std::filesystem::path& target);

/// Throws hmap::Error unless the folder `out` can be replaced as a whole by a set that `command`
/// writes (write_folder_atomic): `out` does not exist and its parent is a writable folder, or it is
/// a folder holding only entries that `command` writes. `owned` lists them as fnmatch patterns
/// ("poses.txt", "rbf_*"); one ending in '/' names a folder ("velodyne/"), the others regular
/// files. Anything else in `out` (a user's own file) is refused by name, before the work.
void check_output_set_folder(const std::filesystem::path& out, std::initializer_list<std::string_view> owned,
                             std::string_view command);

/// Writes a set of files as one: `writer` fills a new staging folder beside `out`
/// (make_staging_folder), which then replaces `out` (replace_folder_atomic). If `writer` throws,
/// the staging folder is removed and `out` is left as it was.
void write_folder_atomic(const std::filesystem::path& out, const std::function<void(const std::filesystem::path& dir)>& writer);

/// Writes files that belong together and a `record` naming them (an image and the YAML that
/// gives its resolution and origin) so that whenever `record` exists, it and every file of
/// `files` are the ones written together. All are first written to temporary files (fsynced);
/// then the old record is removed, the files are renamed into place, and the record last. A kill
/// at any moment leaves the old set, the new set, or the files without their record (a reader of
/// the record then finds none and fails, instead of reading a new image with an old origin);
/// never a record beside files it was not written with.
void write_files_with_record(std::initializer_list<std::pair<std::filesystem::path, std::string_view>> files,
                             const std::filesystem::path& record, std::string_view record_bytes);

/// Atomically replaces `path` with `bytes`.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);

}  // namespace hmap
