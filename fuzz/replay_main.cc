// Replays fuzz inputs through a target's LLVMFuzzerTestOneInput without libFuzzer: every file of every directory
// (or file) given. Built with the normal compiler and run by ctest, so the corpus and every crash reproducer stay
// fixed for good (fuzz/README.md). Exits non-zero only by crashing or by an exception escaping the target.
//
// `--mutations N [--seed S]` then runs the target briefly on N inputs mutated from the corpus (bit flips, bytes
// set to parser-significant values, insertions, deletions, duplicated and spliced ranges, truncation), seeded, so
// CI exercises every reader beyond its seeds without a clang build. libFuzzer's coverage-guided search (fuzz/README.md)
// goes much further; this is the cheap, deterministic part of it that runs on every commit.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

namespace {

// One random edit of `s` (which may come back empty); `other` is another corpus input for splicing.
void Mutate(std::string& s, const std::string& other, std::mt19937_64& rng) {
  static constexpr char kSignificant[] = {'\0', '\xff', '0', '9', '-', '+', '.', 'e', '[', ']', '{', '}', '"',
                                          ',', ':', '\n', ' ', '#', '\\', '\x80', '\x7f'};
  const auto pick = [&](size_t n) { return n == 0 ? size_t{0} : static_cast<size_t>(rng() % n); };
  switch (rng() % 8) {
    case 0:  // flip a bit
      if (!s.empty()) s[pick(s.size())] ^= static_cast<char>(1u << (rng() % 8));
      break;
    case 1:  // a byte set to something parsers care about
      if (!s.empty()) s[pick(s.size())] = kSignificant[pick(sizeof(kSignificant))];
      break;
    case 2:  // insert a few bytes
      s.insert(pick(s.size() + 1), std::string(1 + pick(4), kSignificant[pick(sizeof(kSignificant))]));
      break;
    case 3: {  // delete a range
      const size_t at = pick(s.size()), n = 1 + pick(16);
      if (at < s.size()) s.erase(at, n);
      break;
    }
    case 4: {  // duplicate a range in place
      const size_t at = pick(s.size()), n = 1 + pick(64);
      if (at < s.size()) s.insert(at, s.substr(at, n));
      break;
    }
    case 5:  // truncate
      s.resize(pick(s.size() + 1));
      break;
    case 6: {  // splice a range of another input
      const size_t from = pick(other.size()), n = 1 + pick(64);
      if (from < other.size()) s.insert(pick(s.size() + 1), other.substr(from, n));
      break;
    }
    default: {  // overwrite with a long run of digits (numbers beyond every range)
      if (!s.empty()) s.replace(pick(s.size()), 1, std::string(1 + pick(40), '9'));
      break;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  std::vector<fs::path> files;
  long mutations = 0;
  std::uint64_t seed = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--mutations") == 0 && i + 1 < argc) {
      mutations = std::strtol(argv[++i], nullptr, 10);
      continue;
    }
    if (std::strcmp(argv[i], "--seed") == 0 && i + 1 < argc) {
      seed = std::strtoull(argv[++i], nullptr, 10);
      continue;
    }
    std::error_code ec;
    if (fs::is_directory(argv[i], ec)) {
      for (const auto& e : fs::recursive_directory_iterator(argv[i])) {
        if (e.is_regular_file()) files.push_back(e.path());
      }
    } else if (fs::is_regular_file(argv[i], ec)) {
      files.emplace_back(argv[i]);
    }
  }
  std::sort(files.begin(), files.end());  // the mutations must not depend on the directory order
  std::vector<std::string> inputs;
  for (const auto& f : files) {
    std::ifstream in(f, std::ios::binary);
    inputs.emplace_back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(inputs.back().data()), inputs.back().size());
  }
  std::printf("replayed %zu inputs\n", files.size());
  if (files.empty()) return 1;  // an empty corpus is a broken test, not a pass
  std::mt19937_64 rng(seed);
  for (long m = 0; m < mutations; ++m) {
    std::string s = inputs[static_cast<size_t>(m) % inputs.size()];
    const std::string& other = inputs[static_cast<size_t>(rng() % inputs.size())];
    for (int k = 1 + static_cast<int>(rng() % 4); k > 0; --k) Mutate(s, other, rng);
    // To reproduce a crash: TOPOCAL_FUZZ_LAST=FILE keeps the input being run (then copy it into fuzz/crashes/).
    if (const char* last = std::getenv("TOPOCAL_FUZZ_LAST")) std::ofstream(last, std::ios::binary) << s;
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  }
  if (mutations > 0) std::printf("ran %ld mutated inputs (seed %llu)\n", mutations, static_cast<unsigned long long>(seed));
  return 0;
}
