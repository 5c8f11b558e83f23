#include "util/io.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <pthread.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

namespace topocal::util {
namespace {

namespace fs = std::filesystem;

// ---- paths removed when a signal ends the process -----------------------------------------------------------------

std::recursive_mutex& CleanupMutex() {
  static std::recursive_mutex m;
  return m;
}
std::vector<std::string>& CleanupPaths() {
  static std::vector<std::string> paths;
  return paths;
}

// ---- writing --------------------------------------------------------------------------------------------------------

std::string ErrnoText(int e) {
  if (e == ENOSPC) return "disk full (No space left on device)";
  if (e == EDQUOT) return "disk quota exceeded";
  return std::strerror(e);
}

// Writes all of `content` to `fd`; false with errno set on failure.
bool WriteAll(int fd, std::string_view content) {
  const char* p = content.data();
  size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  return true;
}

// The file a chain of symbolic links ends at (the path itself when it is no link; a dangling link's target).
fs::path ResolveLinks(const std::string& path) {
  fs::path p(path);
  constexpr int kMaxHops = 40;  // Linux's own limit (ELOOP)
  for (int hop = 0; hop < kMaxHops; ++hop) {
    struct stat st {};
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
    std::error_code ec;
    const fs::path target = fs::read_symlink(p, ec);
    if (ec) throw InputError(fmt::format("{}: cannot follow the link: {}", path, ec.message()));
    p = target.is_absolute() ? target : p.parent_path() / target;
  }
  throw InputError(fmt::format("{}: cannot be written: {}", path, std::strerror(ELOOP)));
}

std::atomic<unsigned> g_staging_counter{0};

std::string StagingName(const fs::path& final_path, const char* kind) {
  return fmt::format(".{}.{}-{}-{}", final_path.filename().string(), kind, ::getpid(), g_staging_counter++);
}

}  // namespace

// ---- StagedOutputs --------------------------------------------------------------------------------------------------

struct StagedOutputs::State {
  struct File {
    std::string path;     // as given, for messages
    fs::path final_path;  // where it is published (a link's target)
    fs::path staging;     // the staging file
  };
  struct Stream {
    std::string path;  // a FIFO, a character device, a path under /dev or /proc
    std::string content;
  };
  struct Directory {
    std::string path;
    fs::path staging;
  };
  std::vector<File> files;
  std::vector<Stream> streams;
  std::vector<Directory> directories;
  std::vector<fs::path> created;  // directories this set created (removed again if it is not committed)
  bool committed = false;

  void Track(const fs::path& p) { RegisterCleanupPath(p.string()); }
  // Creates `dir` and its missing parents, remembering the outermost one it created.
  void EnsureDirectory(const fs::path& dir, const std::string& for_path) {
    if (dir.empty()) return;
    fs::path outermost;
    for (fs::path p = dir; !p.empty(); p = p.parent_path()) {
      std::error_code ec;
      if (fs::exists(p, ec)) break;
      outermost = p;
      if (p == p.parent_path()) break;
    }
    if (outermost.empty()) {
      std::error_code ec;
      if (!fs::is_directory(dir, ec))
        throw InputError(fmt::format("{}: {} is not a directory", for_path, dir.string()));
      return;
    }
    Track(outermost);
    created.push_back(outermost);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw InputError(fmt::format("{}: cannot create {}: {}", for_path, dir.string(), ec.message()));
  }
};

StagedOutputs::StagedOutputs() : state_(std::make_unique<State>()) {}

StagedOutputs::~StagedOutputs() {
  std::lock_guard lock(CleanupMutex());
  std::error_code ec;
  for (const auto& f : state_->files) {
    if (!state_->committed) fs::remove(f.staging, ec);
    UnregisterCleanupPath(f.staging.string());
  }
  for (const auto& d : state_->directories) {
    if (!state_->committed) fs::remove_all(d.staging, ec);
    UnregisterCleanupPath(d.staging.string());
  }
  for (auto it = state_->created.rbegin(); it != state_->created.rend(); ++it) {
    if (!state_->committed) fs::remove_all(*it, ec);
    UnregisterCleanupPath(it->string());
  }
}

void StagedOutputs::AddFile(const std::string& path, std::string_view content) {
  if (path.empty()) throw InputError("an output path is empty");
  // "-" is refused rather than guessed: every verb prints its summary on standard output, which would mix with the
  // file (/dev/stdout does that deliberately).
  if (path == "-")
    throw InputError("-: not an output path (topocal writes files; /dev/stdout writes to standard output)");
  // Paths under /dev and /proc (/dev/stdout, /dev/fd/N, /proc/self/fd/N) name an open stream or a device: written
  // directly, never renamed over.
  if (path.rfind("/dev/", 0) == 0 || path.rfind("/proc/", 0) == 0) {
    state_->streams.push_back({path, std::string(content)});
    return;
  }
  struct stat st {};
  mode_t mode = 0666;
  bool exists = false;
  if (::stat(path.c_str(), &st) == 0) {  // follows links: what would be written is the link's target
    if (S_ISDIR(st.st_mode)) throw InputError(fmt::format("{}: cannot be written: is a directory", path));
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) {
      state_->streams.push_back({path, std::string(content)});
      return;
    }
    if (!S_ISREG(st.st_mode)) {
      throw InputError(fmt::format("{}: cannot be written: not a regular file, FIFO or character device", path));
    }
    exists = true;
    mode = st.st_mode & 07777;
  } else if (errno != ENOENT) {
    throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  }
  State::File f;
  f.path = path;
  f.final_path = ResolveLinks(path);  // its directory must exist: a misspelt --out is an error, not a new tree
  f.staging = f.final_path.parent_path() / StagingName(f.final_path, "tmp");
  {
    std::lock_guard lock(CleanupMutex());
    state_->Track(f.staging);
    state_->files.push_back(f);
  }
  const int fd = ::open(f.staging.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, exists ? mode : 0666);
  if (fd < 0) throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  if (exists) (void)::fchmod(fd, mode);  // keep the permissions of the file it replaces
  const bool written = WriteAll(fd, content);
  const int write_errno = errno;
  if (::close(fd) != 0 && written) {
    throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(errno)));
  }
  if (!written) throw InputError(fmt::format("{}: cannot be written: {}", path, ErrnoText(write_errno)));
}

std::string StagedOutputs::AddDirectory(const std::string& path) {
  if (path.empty()) throw InputError("an output directory is empty");
  std::error_code ec;
  if (fs::exists(path, ec) && !fs::is_directory(path, ec)) {
    throw InputError(fmt::format("{}: exists and is not a directory", path));
  }
  fs::path target = fs::path(path).lexically_normal();
  if (target.filename().empty() && target.has_parent_path()) target = target.parent_path();  // "maps/"
  state_->EnsureDirectory(target.parent_path(), path);
  State::Directory d{path, target.parent_path() / StagingName(target, "staging")};
  {
    std::lock_guard lock(CleanupMutex());
    state_->Track(d.staging);
    state_->directories.push_back(d);
  }
  fs::create_directory(d.staging, ec);
  if (ec) throw InputError(fmt::format("{}: cannot create {}: {}", path, d.staging.string(), ec.message()));
  return d.staging.string();
}

void StagedOutputs::Commit() {
  {
    // Held while publishing: a signal arriving now waits until every rename is done.
    std::lock_guard lock(CleanupMutex());
    for (const auto& f : state_->files) {
      std::error_code ec;
      fs::rename(f.staging, f.final_path, ec);
      if (ec) throw InputError(fmt::format("{}: cannot be written: {}", f.path, ec.message()));
    }
    for (const auto& d : state_->directories) {
      std::error_code ec;
      fs::path target = fs::path(d.path).lexically_normal();
      if (target.filename().empty() && target.has_parent_path()) target = target.parent_path();
      fs::create_directories(target, ec);
      if (ec) throw InputError(fmt::format("{}: cannot be created: {}", d.path, ec.message()));
      std::vector<fs::path> entries;
      for (const auto& e : fs::recursive_directory_iterator(d.staging, ec)) entries.push_back(e.path());
      if (ec) throw InputError(fmt::format("{}: cannot be listed: {}", d.staging.string(), ec.message()));
      for (const auto& e : entries) {
        const fs::path to = target / fs::relative(e, d.staging);
        if (fs::is_directory(e)) {
          fs::create_directories(to, ec);
        } else {
          fs::rename(e, to, ec);
        }
        if (ec) throw InputError(fmt::format("{}: cannot be written: {}", to.string(), ec.message()));
      }
      fs::remove_all(d.staging, ec);
    }
    state_->committed = true;  // what is published stays even if a stream below fails
  }
  for (const auto& s : state_->streams) {
    struct stat st {};
    const bool regular = ::stat(s.path.c_str(), &st) == 0 && S_ISREG(st.st_mode);  // /dev/stdout redirected to a file
    const int fd = ::open(s.path.c_str(), O_WRONLY | O_CLOEXEC | (regular ? O_TRUNC : 0));
    if (fd < 0) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(errno)));
    const bool ok = WriteAll(fd, s.content);
    const int e = errno;
    if (::close(fd) != 0 && ok) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(errno)));
    if (!ok) throw InputError(fmt::format("{}: cannot be written: {}", s.path, ErrnoText(e)));
  }
}

void WriteFileAtomic(const std::string& path, std::string_view content) {
  StagedOutputs out;
  out.AddFile(path, content);
  out.Commit();
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot be opened for reading: {}", path, ErrnoText(errno)));
  // A regular file is read in one piece into a string of its size: streaming it through an ostringstream copied
  // every byte two to three times as the buffer grew (issue 15: 10 % of `unit calibrate`, which reads ~21 MB of
  // images to hash them). Anything whose size is unknown (a pipe) still streams.
  std::error_code ec;
  const auto size = std::filesystem::is_regular_file(path, ec) ? std::filesystem::file_size(path, ec) : 0;
  if (!ec && size > 0) {
    std::string bytes(static_cast<size_t>(size), '\0');
    in.read(bytes.data(), static_cast<std::streamsize>(size));
    if (in.bad() || in.gcount() != static_cast<std::streamsize>(size)) {
      throw InputError(fmt::format("{}: read error", path));
    }
    // A file that grew while being read: take the rest too, as the streaming read would.
    if (in.peek() == std::ifstream::traits_type::eof()) return bytes;
    std::ostringstream rest;
    rest << in.rdbuf();
    if (in.bad()) throw InputError(fmt::format("{}: read error", path));
    return bytes + rest.str();
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(fmt::format("{}: read error", path));
  return ss.str();
}

// ---- signals -------------------------------------------------------------------------------------------------------

void RegisterCleanupPath(const std::string& path) {
  std::lock_guard lock(CleanupMutex());
  CleanupPaths().push_back(path);
}

void UnregisterCleanupPath(const std::string& path) {
  std::lock_guard lock(CleanupMutex());
  auto& paths = CleanupPaths();
  const auto it = std::find(paths.rbegin(), paths.rend(), path);
  if (it != paths.rend()) paths.erase(std::next(it).base());
}

DeferSignalCleanup::DeferSignalCleanup() { CleanupMutex().lock(); }
DeferSignalCleanup::~DeferSignalCleanup() { CleanupMutex().unlock(); }

void InstallSignalCleanup() {
  static std::once_flag once;
  std::call_once(once, [] {
    sigset_t set;
    sigemptyset(&set);
    for (const int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&set, sig);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    std::thread([set] {
      int sig = 0;
      if (sigwait(&set, &sig) != 0) return;
      CleanupMutex().lock();  // never released: the process ends below
      std::error_code ec;
      auto& paths = CleanupPaths();
      // Other threads keep running until the signal is raised below: one may still be writing a file into a staging
      // directory, and remove_all fails (ENOTEMPTY) when an entry appears while it empties the directory. Retried
      // until the path is gone; once a directory is removed nothing can be created in it again. (New staging paths
      // cannot appear: registering one takes the mutex held here.)
      for (auto it = paths.rbegin(); it != paths.rend(); ++it) {
        for (int attempt = 0; attempt < 1000; ++attempt) {
          fs::remove_all(*it, ec);
          if (!fs::exists(fs::symlink_status(*it, ec))) break;
        }
      }
      // End with the signal itself, so the parent sees what happened (128 + signal in a shell).
      ::signal(sig, SIG_DFL);
      sigset_t one;
      sigemptyset(&one);
      sigaddset(&one, sig);
      pthread_sigmask(SIG_UNBLOCK, &one, nullptr);
      ::raise(sig);
      ::_exit(128 + sig);
    }).detach();
  });
}

}  // namespace topocal::util
