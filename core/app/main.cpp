// sphnl: the command-line front end. Subcommands: run (simulate the dam break
// of paper §2.2 and write outputs), neighbours (neighbour search on any point
// cloud), help, --version.
#include <cstdio>
#include <cstring>
#include <string>

#include "neighbours_tool.hpp"
#include "run.hpp"
#include "sphnl_revision.hpp"

namespace {

const char* const kUsage =
    "usage: sphnl <command> [options]\n"
    "\n"
    "commands:\n"
    "  run         run the dam break with obstacle (Dominguez et al. 2011, section 2.2):\n"
    "              sphnl run [--config FILE.json] [--set key=value]... [--out DIR] [--quiet]\n"
    "  neighbours  neighbour search on a point cloud:\n"
    "              sphnl neighbours --input points.csv --radius R [...] --out counts.csv\n"
    "  help        this text; `sphnl <command> --help` for the options of a command\n"
    "  --version   git revision and build type\n";

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  const std::string command = argv[1];
  if (command == "run") return sphnl::run_main(argc - 1, argv + 1);
  if (command == "neighbours") return sphnl::neighbours_main(argc - 1, argv + 1);
  if (command == "help" || command == "--help" || command == "-h") {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (command == "--version" || command == "version") {
    std::printf("sphnl %s (%s build, %s)\n", SPHNL_GIT_REVISION, SPHNL_BUILD_TYPE, SPHNL_COMPILER);
    return 0;
  }
  std::fprintf(stderr, "sphnl: unknown command or option '%s'\n\n%s", argv[1], kUsage);
  return 2;
}
