// FileBytes: mmap with a read() fallback.
#include "common/scene/file_bytes.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <utility>

#include "common/base/error.h"

namespace rtc {

FileBytes::FileBytes(const std::filesystem::path& path) {
  const std::string name = path.string();
  // open() would stop at the NUL and read another file than the one named (a glTF buffer URI,
  // an MTL library: names that come from files).
  // The message shows it as \0: a raw NUL would end what() there, reason and all.
  if (const std::size_t nul = name.find('\0'); nul != std::string::npos) {
    std::string shown = name;
    for (std::size_t at = nul; at != std::string::npos; at = shown.find('\0', at + 2)) shown.replace(at, 1, "\\0");
    throw_at(shown, 0, "file name contains a NUL byte");
  }
  const int fd = ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    throw_at(name, 0, std::string("cannot open the file: ") + std::strerror(errno));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || S_ISDIR(st.st_mode)) {
    ::close(fd);
    throw_at(name, 0, "cannot read the file (a directory?)");
  }
  // A device (/dev/zero, a terminal) never ends or blocks for input: a file named by a scene
  // must be a regular file or a pipe.
  if (!S_ISREG(st.st_mode) && !S_ISFIFO(st.st_mode)) {
    ::close(fd);
    throw_at(name, 0, "not a regular file or a pipe (a device or socket?)");
  }
  if (S_ISREG(st.st_mode) && st.st_size > 0) {
    void* map = ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ,
                       MAP_PRIVATE | MAP_POPULATE, fd, 0);
    if (map != MAP_FAILED) {
      map_ = map;
      size_ = static_cast<std::size_t>(st.st_size);
      ::close(fd);
      return;
    }
  }
  // Not mappable (empty, a pipe, ...): read it.
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      ::close(fd);
      throw_at(name, 0, std::string("read error: ") + std::strerror(errno));
    }
    copy_.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
}

FileBytes::~FileBytes() { release(); }

FileBytes::FileBytes(FileBytes&& other) noexcept
    : map_(std::exchange(other.map_, nullptr)),
      size_(std::exchange(other.size_, 0)),
      copy_(std::move(other.copy_)) {}

FileBytes& FileBytes::operator=(FileBytes&& other) noexcept {
  if (this != &other) {
    release();
    map_ = std::exchange(other.map_, nullptr);
    size_ = std::exchange(other.size_, 0);
    copy_ = std::move(other.copy_);
  }
  return *this;
}

void FileBytes::release() {
  if (map_ != nullptr) ::munmap(map_, size_);
  map_ = nullptr;
  size_ = 0;
}

}  // namespace rtc
