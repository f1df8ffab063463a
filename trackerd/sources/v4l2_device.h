// SPDX-License-Identifier: Apache-2.0
#pragma once
// The thin layer between V4l2Camera and the kernel: open/ioctl/mmap/poll/close on a video node, and
// the list of video nodes in sysfs. Everything above it is kernel-free, so a fake device in the
// tests (tests/unit/test_devices.cpp) drives every path of the camera: negotiation, streaming,
// timestamps, EBUSY, a device that disappears (ENODEV) and comes back.
//
// Error convention: calls return a negative errno (-ENOENT, -EBUSY, ...) instead of setting the
// global errno, so a fake cannot forget to set it and a caller cannot read a stale one.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace fovea::trackerd {

class V4l2Device {
 public:
  virtual ~V4l2Device() = default;
  // Returns a file descriptor (>= 0) or -errno.
  virtual int open(const std::string& path, int flags) = 0;
  virtual void close(int fd) = 0;
  // VIDIOC_* request on fd; 0 or -errno. EINTR is retried by the implementation.
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  // Maps `length` bytes at `offset` (from VIDIOC_QUERYBUF) read/write shared; 0 or -errno.
  virtual int mmap(int fd, std::size_t length, std::int64_t offset, void** address) = 0;
  virtual void munmap(void* address, std::size_t length) = 0;
  // Waits up to timeout_ms for `events` on fd; returns the revents mask (> 0), 0 on timeout, or
  // -errno.
  virtual int poll(int fd, short events, int timeout_ms) = 0;
};

// The kernel: ::open, ::ioctl (retrying EINTR), ::mmap, ::poll.
std::shared_ptr<V4l2Device> real_v4l2_device();

// One /dev/videoN node as sysfs describes it.
struct VideoNode {
  std::string path;            // "/dev/video0"
  std::string name;            // sysfs "name", e.g. "UVC Camera (046d:0825)"
  int index = 0;               // sysfs "index": 0 for a UVC camera's capture node, 1 for its metadata node
  bool usb = false;            // true when the node belongs to a USB device (vid/pid/bus/address valid)
  std::uint16_t vid = 0, pid = 0;
  std::uint8_t bus = 0, address = 0;
};

// The video nodes present on the machine (sorted by node number).
class VideoNodeDirectory {
 public:
  virtual ~VideoNodeDirectory() = default;
  virtual std::vector<VideoNode> list() const = 0;
};

// Reads <class_root>/videoN/{name,index} and, for USB devices, <class_root>/videoN/device/../
// {idVendor,idProduct,busnum,devnum}; node paths are <dev_root>/videoN. Tests point the roots at a
// temporary tree.
class SysfsVideoNodes final : public VideoNodeDirectory {
 public:
  explicit SysfsVideoNodes(std::string class_root = "/sys/class/video4linux", std::string dev_root = "/dev");
  std::vector<VideoNode> list() const override;

 private:
  std::string class_root_, dev_root_;
};

// "/dev/video0 (UVC Camera), /dev/video2 (Integrated IR Camera)" or "none".
std::string describe_video_nodes(const std::vector<VideoNode>& nodes);

// The capture node of the USB device vid:pid (at bus/address when those are non-zero): the node
// with the lowest sysfs index, then the lowest number. Empty when there is none (yet).
std::string find_video_node(const VideoNodeDirectory& nodes, std::uint16_t vid, std::uint16_t pid,
                            std::uint8_t bus = 0, std::uint8_t address = 0);

}  // namespace fovea::trackerd
