// SPDX-License-Identifier: Apache-2.0
#include "sources/v4l2_device.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <filesystem>
#include <fstream>

namespace fovea::trackerd {

namespace {

class KernelV4l2Device final : public V4l2Device {
 public:
  int open(const std::string& path, int flags) override {
    const int fd = ::open(path.c_str(), flags | O_CLOEXEC);
    return fd >= 0 ? fd : -errno;
  }
  void close(int fd) override { ::close(fd); }
  int ioctl(int fd, unsigned long request, void* arg) override {
    int r = 0;
    do {
      r = ::ioctl(fd, request, arg);
    } while (r < 0 && errno == EINTR);
    return r < 0 ? -errno : 0;
  }
  int mmap(int fd, std::size_t length, std::int64_t offset, void** address) override {
    void* p = ::mmap(nullptr, length, PROT_READ | PROT_WRITE, MAP_SHARED, fd, static_cast<off_t>(offset));
    if (p == MAP_FAILED) return -errno;
    *address = p;
    return 0;
  }
  void munmap(void* address, std::size_t length) override { ::munmap(address, length); }
  int poll(int fd, short events, int timeout_ms) override {
    pollfd p{fd, events, 0};
    const int r = ::poll(&p, 1, timeout_ms);
    if (r < 0) return -errno;
    return r == 0 ? 0 : (p.revents != 0 ? p.revents : 0);
  }
};

std::string read_line(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string line;
  if (!in || !std::getline(in, line)) return {};
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r' || line.back() == ' ')) line.pop_back();
  return line;
}

template <typename T>
bool parse_number(const std::string& text, int base, T& out) {
  if (text.empty()) return false;
  const char* end = text.data() + text.size();
  const auto r = std::from_chars(text.data(), end, out, base);
  return r.ec == std::errc{} && r.ptr == end;
}

// "video12" -> 12, anything else -> -1.
int node_number(const std::string& name) {
  if (name.rfind("video", 0) != 0) return -1;
  int n = -1;
  return parse_number(name.substr(5), 10, n) ? n : -1;
}

}  // namespace

std::shared_ptr<V4l2Device> real_v4l2_device() { return std::make_shared<KernelV4l2Device>(); }

SysfsVideoNodes::SysfsVideoNodes(std::string class_root, std::string dev_root)
    : class_root_(std::move(class_root)), dev_root_(std::move(dev_root)) {}

std::vector<VideoNode> SysfsVideoNodes::list() const {
  namespace fs = std::filesystem;
  std::vector<std::pair<int, VideoNode>> found;
  std::error_code ec;
  for (fs::directory_iterator it(class_root_, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string entry = it->path().filename().string();
    const int number = node_number(entry);
    if (number < 0) continue;
    VideoNode node;
    node.path = dev_root_ + "/" + entry;
    node.name = read_line(it->path() / "name");
    parse_number(read_line(it->path() / "index"), 10, node.index);
    // videoN/device is the USB interface; its parent directory is the USB device with the ids.
    // The path is resolved by the kernel (symlink first, then ".."), as sysfs intends.
    const fs::path usb = it->path() / "device" / "..";
    std::uint16_t vid = 0, pid = 0;
    unsigned bus = 0, address = 0;
    if (parse_number(read_line(usb / "idVendor"), 16, vid) && parse_number(read_line(usb / "idProduct"), 16, pid)) {
      node.usb = true;
      node.vid = vid;
      node.pid = pid;
      if (parse_number(read_line(usb / "busnum"), 10, bus)) node.bus = static_cast<std::uint8_t>(bus);
      if (parse_number(read_line(usb / "devnum"), 10, address)) node.address = static_cast<std::uint8_t>(address);
    }
    found.emplace_back(number, std::move(node));
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<VideoNode> nodes;
  nodes.reserve(found.size());
  for (auto& f : found) nodes.push_back(std::move(f.second));
  return nodes;
}

std::string describe_video_nodes(const std::vector<VideoNode>& nodes) {
  if (nodes.empty()) return "none";
  std::string text;
  for (const auto& n : nodes) {
    if (!text.empty()) text += ", ";
    text += n.path;
    if (!n.name.empty()) text += " (" + n.name + ")";
  }
  return text;
}

std::string find_video_node(const VideoNodeDirectory& nodes, std::uint16_t vid, std::uint16_t pid, std::uint8_t bus,
                            std::uint8_t address) {
  const std::vector<VideoNode> all = nodes.list();
  const VideoNode* best = nullptr;
  for (const auto& n : all) {  // sorted by node number, so the first of equal index wins
    if (!n.usb || n.vid != vid || n.pid != pid) continue;
    if (bus != 0 && n.bus != 0 && n.bus != bus) continue;
    if (address != 0 && n.address != 0 && n.address != address) continue;
    if (best == nullptr || n.index < best->index) best = &n;
  }
  return best != nullptr ? best->path : std::string{};
}

}  // namespace fovea::trackerd
