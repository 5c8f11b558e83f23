// topocal — the program users run. It only chooses the program that runs the command line and hands it over with
// execv: the same process, so the same process id, signals, standard streams and exit code. Loading shared libraries
// is most of a short process' cost (docs/performance.md, "Start-up"), and this choice needs none: the program links
// the C library alone (no C++ library either), so a verb pays for the libraries of the program that runs it only.
//  - `--version`, and `sweep` without a help flag: topocal-sweep (sweep_main.cc), linked against model, topo, Ceres
//    and fmt but no OpenCV; it hands a sweep with --correct or --maps on to topocal-full.
//  - `detect` without a help flag: topocal-detect (detect_main.cc), without the calibration, drawing, database and
//    digest libraries no capture needs.
//  - Every other command line, and every --help: topocal-full (main.cc), every verb.
// Both are installed in <prefix>/<libexecdir>, as this program is in <prefix>/<bindir>; the build tree mirrors that
// layout (tools/CMakeLists.txt).
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

namespace {

// The program that runs the command line: topocal-sweep for `--version` alone or `sweep` without a help flag,
// topocal-detect for `detect` without a help flag (`--quiet` may stand anywhere), topocal-full for any other.
const char* ProgramFor(int argc, char** argv) {
  int first = 0, count = 0;
  bool help = false;
  for (int i = 1; i < argc; ++i) {
    if (strcmp(argv[i], "--quiet") == 0) continue;
    if (count++ == 0) first = i;
    help = help || strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "--help-all") == 0;
  }
  if (count == 0) return "topocal-full";
  if (count == 1 && strcmp(argv[first], "--version") == 0) return "topocal-sweep";
  if (help) return "topocal-full";
  if (strcmp(argv[first], "sweep") == 0) return "topocal-sweep";
  if (strcmp(argv[first], "detect") == 0) return "topocal-detect";
  return "topocal-full";
}

}  // namespace

int main(int argc, char** argv) {
  const char* program = ProgramFor(argc, argv);
  // <this executable's directory>/../<libexecdir>/<program>
  char path[PATH_MAX + 64];
  const ssize_t n = readlink("/proc/self/exe", path, PATH_MAX);
  if (n < 0) {
    fprintf(stderr, "topocal: cannot locate this executable (/proc/self/exe: %s) to run %s\n", strerror(errno), program);
    return 1;
  }
  path[n] = '\0';
  for (int up = 0; up < 2; ++up) {
    char* slash = strrchr(path, '/');
    if (slash) *slash = '\0';
  }
  char full[PATH_MAX + 256];
  snprintf(full, sizeof full, "%s/%s/%s", path, TOPOCAL_INSTALL_LIBEXECDIR, program);
  execv(full, argv);
  fprintf(stderr, "topocal: cannot run %s: %s (install topocal with `cmake --install`)\n", full, strerror(errno));
  return 1;
}
