// Fuzzes the CLI's flag layer itself: CLI11's parsing of every command's options, with hmap's
// validators and transforms (apps/hmap, hmap::cli::configure_app). The input is a command line,
// one argument per line (at most 64), without the program name: "map\n--cell\n0.1\nscan.pcd".
// The commands are not run (the parse stops before their callbacks): what is checked is the parsing alone.
//
// Accepted, or refused with a CLI::Error or an hmap::Error whose message, as main() prints it,
// is one line of printable text; any other exception (a bare std::invalid_argument from a
// conversion, say) escapes and is reported as a crash, as are the sanitizers' findings.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <string>
#include <string_view>
#include <vector>

#include "cli_common.hpp"
#include "fuzz_target.hpp"
#include "hmap/core/error.hpp"

namespace {

/// Thrown by the root's parse-complete callback, which CLI11 runs after every option has been
/// converted, validated and checked for requirements and before any command's callback: the
/// commands are parsed, not run. (Clearing the commands' callbacks instead destroyed the option
/// structs they own, which the options are bound to: a use after free under ASan.)
struct ParsedOnly {};

}  // namespace

HMAP_FUZZ_ENTRY(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> args;
  for (std::size_t pos = 0; pos <= text.size() && args.size() < 64;) {
    const std::size_t end = std::min(text.find('\n', pos), text.size());
    args.emplace_back(text.substr(pos, end - pos));
    pos = end + 1;
  }
  std::reverse(args.begin(), args.end());  // CLI11 takes the arguments last first
  CLI::App app{"hmap"};
  hmap::cli::configure_app(app);
  app.parse_complete_callback([] { throw ParsedOnly{}; });
  try {
    app.parse(args);
  } catch (const ParsedOnly&) {
    // parsed and validated; the command would run now
  } catch (const CLI::Error& e) {
    // main() prints a ParseError's what() through hmap::one_line; help and version are not errors.
    hmap::fuzz::check_message(hmap::Error(e.what()));
  } catch (const hmap::Error& e) {
    hmap::fuzz::check_message(e);
  }
  hmap::cli::memory_budget() = hmap::MemoryBudget{};  // --max-memory sets it while parsing
  return 0;
}
