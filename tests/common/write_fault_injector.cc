// A write-fault injector for tests, loaded into a real binary with
// LD_PRELOAD: while the control file exists, every write, sync, truncate
// and allocation of a file whose path starts with the prefix fails with the
// errno named in the control file (ENOSPC, EDQUOT, EFBIG, EIO, EROFS,
// EPERM). The store's own code runs unchanged above the failing system
// calls, as it would on a full, broken or read-only disk.
//
//   BITEWISE_WRITE_FAULT_FILE    the control file (its content: the errno)
//   BITEWISE_WRITE_FAULT_PREFIX  which files fail (e.g. the database path)
// or else (the default)
//   BITEWISE_WRITE_FAULT_SIBLING a file name ("bitewise-write-fault"): a
//                                file fails while a control file of this
//                                name is in its directory
//
// Without a control file, every call goes straight to the C library.
#include <dlfcn.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {

const char* Env(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr && *value != '\0' ? value : nullptr;
}

// The errno named in the file `control`, or 0.
int ErrnoIn(const char* control) {
  const int cfd = open(control, O_RDONLY | O_CLOEXEC);
  if (cfd < 0) return 0;
  char name[32] = {};
  const ssize_t n = read(cfd, name, sizeof(name) - 1);
  close(cfd);
  if (n <= 0) return 0;
  static const struct {
    const char* name;
    int error;
  } kErrors[] = {{"ENOSPC", ENOSPC}, {"EDQUOT", EDQUOT}, {"EFBIG", EFBIG},
                 {"EIO", EIO},       {"EROFS", EROFS},   {"EPERM", EPERM}};
  for (const auto& e : kErrors) {
    if (std::strncmp(name, e.name, std::strlen(e.name)) == 0) return e.error;
  }
  return 0;
}

// The errno to fail with, or 0 when `fd` is not to fail now.
int FaultFor(int fd) {
  static const char* const control = Env("BITEWISE_WRITE_FAULT_FILE");
  static const char* const prefix = Env("BITEWISE_WRITE_FAULT_PREFIX");
  // Without a control file and prefix, the sibling mode (by default
  // "bitewise-write-fault"): a test binary needs only LD_PRELOAD.
  static const char* const sibling =
      control != nullptr && prefix != nullptr
          ? nullptr
          : (Env("BITEWISE_WRITE_FAULT_SIBLING") != nullptr
                 ? Env("BITEWISE_WRITE_FAULT_SIBLING")
                 : "bitewise-write-fault");
  const int saved = errno;
  int result = 0;
  char link[64];
  std::snprintf(link, sizeof(link), "/proc/self/fd/%d", fd);
  char path[4096];
  const ssize_t len = readlink(link, path, sizeof(path) - 1);
  if (len > 0 && path[0] == '/') {
    path[len] = '\0';
    if (sibling != nullptr) {
      // The control file beside the written one: each directory (a test's
      // store, a database's files) fails on its own.
      char* slash = std::strrchr(path, '/');
      if (static_cast<size_t>(slash - path) + 2 + std::strlen(sibling) <
          sizeof(path)) {
        std::strcpy(slash + 1, sibling);
        result = ErrnoIn(path);
      }
    } else if (std::strncmp(path, prefix, std::strlen(prefix)) == 0) {
      result = ErrnoIn(control);
    }
  }
  errno = saved;
  return result;
}

template <typename F>
F Next(const char* name) {
  return reinterpret_cast<F>(dlsym(RTLD_NEXT, name));
}

}  // namespace

extern "C" {

ssize_t write(int fd, const void* buf, size_t count) {
  static auto next = Next<ssize_t (*)(int, const void*, size_t)>("write");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, buf, count);
}

ssize_t pwrite(int fd, const void* buf, size_t count, off_t offset) {
  static auto next =
      Next<ssize_t (*)(int, const void*, size_t, off_t)>("pwrite");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, buf, count, offset);
}

ssize_t pwrite64(int fd, const void* buf, size_t count, off64_t offset) {
  static auto next =
      Next<ssize_t (*)(int, const void*, size_t, off64_t)>("pwrite64");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, buf, count, offset);
}

int fsync(int fd) {
  static auto next = Next<int (*)(int)>("fsync");
  if (const int error = FaultFor(fd)) {
    errno = error == ENOSPC || error == EDQUOT || error == EFBIG ? EIO : error;
    return -1;
  }
  return next(fd);
}

int fdatasync(int fd) {
  static auto next = Next<int (*)(int)>("fdatasync");
  if (const int error = FaultFor(fd)) {
    errno = error == ENOSPC || error == EDQUOT || error == EFBIG ? EIO : error;
    return -1;
  }
  return next(fd);
}

int ftruncate(int fd, off_t length) noexcept {
  static auto next = Next<int (*)(int, off_t)>("ftruncate");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, length);
}

int ftruncate64(int fd, off64_t length) noexcept {
  static auto next = Next<int (*)(int, off64_t)>("ftruncate64");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, length);
}

int fallocate(int fd, int mode, off_t offset, off_t length) {
  static auto next = Next<int (*)(int, int, off_t, off_t)>("fallocate");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, mode, offset, length);
}

int fallocate64(int fd, int mode, off64_t offset, off64_t length) {
  static auto next = Next<int (*)(int, int, off64_t, off64_t)>("fallocate64");
  if (const int error = FaultFor(fd)) {
    errno = error;
    return -1;
  }
  return next(fd, mode, offset, length);
}

}  // extern "C"
