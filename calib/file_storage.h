#pragma once
// The one way topocal hands text to cv::FileStorage (calibration files, Kalibr target YAML): OpenCV's YAML, XML and
// JSON parsers recurse once per nesting level and overflowed the stack (SIGSEGV) on ~1e5 nested '[', so
// the size and the nesting depth are checked on the text first; cv::Exception from the parser becomes an
// InputError naming the file. Everything read from the storage afterwards is still checked by the caller.
#include <cstddef>
#include <opencv2/core.hpp>
#include <string>

#include "util/io.h"

namespace topocal::calib {

inline constexpr size_t kMaxFileStorageBytes = 16u << 20;  // calibration files are a few kB, targets < 1 kB
inline constexpr int kMaxFileStorageDepth = 64;            // topocal's own files nest 2 levels deep

// The nesting depth the text could reach in any of FileStorage's formats, counted without parsing: flow brackets
// '[' '{' outside quoted strings, XML elements, and block sequences opened on one line ("- - - x"). An upper bound
// of the parser's recursion (over-counting only refuses absurd files).
int FileStorageNestingBound(const std::string& text);

// The first integer literal outside quoted strings beyond int's range ("line N: TOKEN"), or "" if none: OpenCV
// reads integers with (int)strtol, so targetCols: 4294967298 silently became 2.
std::string FileStorageIntegerOutOfRange(const std::string& text);

// The first byte >= 0x80 outside a quoted string or a '#' comment ("line N"), or "" if none. OpenCV 4.6's YAML
// parser loops forever on some such bytes where a key should start (the libFuzzer reproducer in
// fuzz/crashes/calibration_yaml/hang-non-ascii-key.yaml); OpenCV itself quotes every string that is not ASCII, and
// keys are ASCII, so a YAML text with one is refused before the parser sees it.
std::string FileStorageUnquotedNonAscii(const std::string& text);

// The first line of a YAML text ("line N") that is neither blank, a comment, a directive or document marker, a list
// item ("- ...") nor a block-mapping key ("KEY: ..."), outside flow brackets and quotes, or that is indented less
// than the document's first line of content; "" if none. OpenCV 4.6's
// YAML parser loops forever on some such lines (libFuzzer: " s:5" then "-- -", reproducers in
// fuzz/crashes/calibration_yaml/), and no calibration, target or camchain file has one.
std::string FileStorageYamlLineProblem(const std::string& text);

// Opens `text` (YAML, with or without the "%YAML:1.0" header Kalibr's files lack; XML; JSON) from memory.
// Throws util::InputError "ORIGIN: problem" when it is too large, nested too deep or not parseable.
cv::FileStorage OpenFileStorage(const std::string& text, const std::string& origin);

// Runs `read` (which reads nodes of a storage OpenFileStorage opened) and turns whatever OpenCV throws while it
// reads into one InputError naming the origin: cv::Exception, and the std::length_error / bad_alloc its node
// readers throw on malformed matrices (the fuzzer's `camera_matrix` without `dt` aborted the process). An
// InputError from `read` passes unchanged.
template <typename Read>
auto ReadFileStorage(const std::string& origin, const char* what, Read&& read) -> decltype(read()) {
  const auto fail = [&](std::string why) -> decltype(read()) {
    for (char& c : why) c = c == '\n' ? ' ' : c;
    if (why.size() > 100) why = why.substr(0, 97) + "...";
    throw util::InputError(origin + ": not readable as " + what + " (" + why + ")");
  };
  try {
    return read();
  } catch (const util::InputError&) {
    throw;
  } catch (const cv::Exception& e) {
    return fail(e.err);
  } catch (const std::exception& e) {
    return fail(e.what());
  }
}

}  // namespace topocal::calib
