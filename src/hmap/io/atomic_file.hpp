#pragma once
// Writing a file so that readers see either the old content or the complete new one, never a
// half-written file: write a temporary file beside it, fsync, then rename() over the target.

#include <filesystem>
#include <functional>
#include <ostream>
#include <string_view>

namespace hmap {

/// Calls `writer` with a stream onto a temporary file `.NAME.tmp.PID.RANDOM` in the target's
/// folder, flushes and fsyncs it, and renames it to `path` (replacing any file there; an existing
/// file's permission bits are kept). If `writer` throws or any step fails, the temporary file is
/// removed, `path` is left as it was, and hmap::Error naming `path` is thrown.
void write_file_atomic(const std::filesystem::path& path, const std::function<void(std::ostream&)>& writer);

/// Atomically replaces `path` with `bytes`.
void write_file_atomic(const std::filesystem::path& path, std::string_view bytes);

}  // namespace hmap
