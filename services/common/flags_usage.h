// The command line of every bitewise binary: `--help` that lists the
// binary's own flags, and a parse that refuses what is not a flag.
#ifndef BITEWISE_SERVICES_COMMON_FLAGS_USAGE_H_
#define BITEWISE_SERVICES_COMMON_FLAGS_USAGE_H_

#include <cstdio>
#include <cstdlib>
#include <vector>

#include "absl/flags/parse.h"
#include "absl/flags/usage_config.h"
#include "absl/strings/match.h"
#include "absl/strings/string_view.h"

namespace bitewise {

// Makes `--help` list each binary's own flags. Abseil's default shows only
// flags defined in a file named like the program, and every bitewise main
// is main.cc, so `--help` said "No flags matched". Call before
// ParseFlagsOnly; --helpfull still lists Abseil's own flags too.
inline void ShowOwnFlagsInHelp() {
  absl::FlagsUsageConfig config;
  config.contains_help_flags = [](absl::string_view file) {
    return !absl::StrContains(file, "absl/");
  };
  config.contains_helpshort_flags = config.contains_help_flags;
  absl::SetFlagsUsageConfig(config);
}

// absl::ParseCommandLine for a binary that takes flags only. Abseil leaves
// anything that is not a flag as a positional argument, which the binary
// would ignore and run on its default instead: `bitewise-health
// 127.0.0.1:50054` checked the BanditService's default address, and
// `--allow_plaintext_remote false` turns the boolean on and leaves "false"
// over. So an argument left over stops the start (exit code 1) with a
// message naming it.
inline void ParseFlagsOnly(int argc, char** argv) {
  const std::vector<char*> rest = absl::ParseCommandLine(argc, argv);
  if (rest.size() <= 1) return;
  std::fprintf(stderr,
               "%s: unexpected argument \"%s\": this program takes flags "
               "only (--name=value; --help lists them)\n",
               argv[0], rest[1]);
  std::exit(1);
}

}  // namespace bitewise

#endif  // BITEWISE_SERVICES_COMMON_FLAGS_USAGE_H_
