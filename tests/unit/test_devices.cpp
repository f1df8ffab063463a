// SPDX-License-Identifier: Apache-2.0
// Eye-camera and device sources: V4L2 camera against a fake kernel device, recorded video files,
// USB hotplug against a fake enumerator. No camera or USB device is needed.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "source_api/image_header.h"
#include "sources/usb_hotplug.h"
#include "sources/v4l2_camera.h"
#include "sources/v4l2_device.h"
#include "sources/video_file.h"

using namespace fovea::trackerd;
namespace fs = std::filesystem;

namespace {

struct FakeFormat {
  std::uint32_t fourcc;
  std::uint32_t width, height;
  std::vector<std::uint32_t> fps;  // discrete rates; empty: the driver lists no intervals
};

struct FakeFrame {
  std::vector<std::uint8_t> data;
  std::uint32_t sequence = 0;
  std::int64_t time_ns = 0;
  bool error = false;
};

struct FakeControl {
  std::int32_t minimum, maximum, default_value;
};

// Emulates a V4L2 capture device at the ioctl level, including an unplug (ENODEV on the open file,
// ENOENT on open) and a replug.
class FakeV4l2Device final : public V4l2Device {
 public:
  std::string path = "/dev/video0";
  std::string card = "Fake IR Camera";
  std::uint32_t caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  std::vector<FakeFormat> formats;
  std::uint32_t padding = 0;  // extra bytes per line
  bool monotonic = true;
  std::map<unsigned long, int> fail;  // request -> errno
  int open_error = 0;
  std::optional<FakeControl> exposure, gain;
  std::map<std::uint32_t, std::int32_t> controls_set;
  std::deque<FakeFrame> frames;

  // Observations.
  int opens = 0, open_fds = 0, open_attempts = 0;
  long mapped_bytes = 0;
  v4l2_format format{};
  v4l2_fract timeperframe{1, 30};
  bool streaming = false;

  void unplug() {
    present_ = false;
    gone_generation_ = generation_;
  }
  void replug() {
    present_ = true;
    ++generation_;
  }

  int open(const std::string& p, int flags) override {
    ++open_attempts;
    EXPECT_NE(flags & O_NONBLOCK, 0);
    if (!present_ || p != path) return -ENOENT;
    if (open_error != 0) return -open_error;
    ++opens;
    ++open_fds;
    streaming = false;
    storage_.clear();
    queued_.clear();
    return 100 + generation_;
  }
  void close(int) override { --open_fds; }

  int ioctl(int fd, unsigned long request, void* arg) override {
    if (fd - 100 <= gone_generation_ && !present_) return -ENODEV;
    if (const auto it = fail.find(request); it != fail.end()) return -it->second;
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* c = static_cast<v4l2_capability*>(arg);
        std::snprintf(reinterpret_cast<char*>(c->card), sizeof c->card, "%s", card.c_str());
        c->capabilities = caps | V4L2_CAP_DEVICE_CAPS;
        c->device_caps = caps;
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* d = static_cast<v4l2_fmtdesc*>(arg);
        const auto fourccs = distinct_fourccs();
        if (d->index >= fourccs.size()) return -EINVAL;
        d->pixelformat = fourccs[d->index];
        return 0;
      }
      case VIDIOC_ENUM_FRAMESIZES: {
        auto* s = static_cast<v4l2_frmsizeenum*>(arg);
        std::uint32_t i = 0;
        for (const auto& f : formats) {
          if (f.fourcc != s->pixel_format) continue;
          if (i++ == s->index) {
            s->type = V4L2_FRMSIZE_TYPE_DISCRETE;
            s->discrete = {f.width, f.height};
            return 0;
          }
        }
        return -EINVAL;
      }
      case VIDIOC_ENUM_FRAMEINTERVALS: {
        auto* iv = static_cast<v4l2_frmivalenum*>(arg);
        for (const auto& f : formats) {
          if (f.fourcc != iv->pixel_format || f.width != iv->width || f.height != iv->height) continue;
          if (iv->index >= f.fps.size()) return -EINVAL;
          iv->type = V4L2_FRMIVAL_TYPE_DISCRETE;
          iv->discrete = {1, f.fps[iv->index]};
          return 0;
        }
        return -EINVAL;
      }
      case VIDIOC_G_FMT:
        *static_cast<v4l2_format*>(arg) = format;
        return 0;
      case VIDIOC_S_FMT: {
        auto* f = static_cast<v4l2_format*>(arg);
        const FakeFormat* match = nullptr;
        for (const auto& ff : formats) {
          if (ff.fourcc == f->fmt.pix.pixelformat && (match == nullptr || (ff.width == f->fmt.pix.width &&
                                                                            ff.height == f->fmt.pix.height))) {
            match = &ff;
          }
        }
        if (match == nullptr) match = &formats.front();  // drivers substitute rather than fail
        f->fmt.pix.pixelformat = match->fourcc;
        f->fmt.pix.width = match->width;
        f->fmt.pix.height = match->height;
        const std::uint32_t bpp = match->fourcc == V4L2_PIX_FMT_YUYV ? 2 : 1;
        f->fmt.pix.bytesperline = match->fourcc == V4L2_PIX_FMT_MJPEG ? 0 : match->width * bpp + padding;
        f->fmt.pix.sizeimage = (match->width * bpp + padding) * match->height + 4096;
        format = *f;
        return 0;
      }
      case VIDIOC_G_PARM:
      case VIDIOC_S_PARM: {
        auto* p = static_cast<v4l2_streamparm*>(arg);
        if (request == VIDIOC_S_PARM) timeperframe = p->parm.capture.timeperframe;
        p->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
        p->parm.capture.timeperframe = timeperframe;
        return 0;
      }
      case VIDIOC_QUERYCTRL: {
        auto* q = static_cast<v4l2_queryctrl*>(arg);
        const auto& c = q->id == V4L2_CID_EXPOSURE_ABSOLUTE ? exposure : q->id == V4L2_CID_GAIN ? gain : std::nullopt;
        if (!c) return -EINVAL;
        q->minimum = c->minimum;
        q->maximum = c->maximum;
        q->default_value = c->default_value;
        return 0;
      }
      case VIDIOC_S_CTRL: {
        auto* c = static_cast<v4l2_control*>(arg);
        controls_set[c->id] = c->value;
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* r = static_cast<v4l2_requestbuffers*>(arg);
        EXPECT_EQ(r->memory, V4L2_MEMORY_MMAP);
        if (r->count == 0) {
          EXPECT_EQ(mapped_bytes, 0) << "buffers released while still mapped";
          storage_.clear();
          return 0;
        }
        r->count = std::min<std::uint32_t>(r->count, 6);
        storage_.assign(r->count, std::vector<std::uint8_t>(format.fmt.pix.sizeimage));
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* b = static_cast<v4l2_buffer*>(arg);
        if (b->index >= storage_.size()) return -EINVAL;
        b->length = static_cast<std::uint32_t>(storage_[b->index].size());
        b->m.offset = b->index * 65536;
        return 0;
      }
      case VIDIOC_QBUF:
        queued_.push_back(static_cast<v4l2_buffer*>(arg)->index);
        return 0;
      case VIDIOC_STREAMON:
        streaming = true;
        return 0;
      case VIDIOC_STREAMOFF:
        streaming = false;
        return 0;
      case VIDIOC_DQBUF: {
        if (!streaming || frames.empty() || queued_.empty()) return -EAGAIN;
        auto* b = static_cast<v4l2_buffer*>(arg);
        const FakeFrame f = frames.front();
        frames.pop_front();
        b->index = queued_.front();
        queued_.pop_front();
        auto& s = storage_[b->index];
        EXPECT_LE(f.data.size(), s.size());
        std::copy(f.data.begin(), f.data.end(), s.begin());
        b->bytesused = static_cast<std::uint32_t>(f.data.size());
        b->sequence = f.sequence;
        b->flags = (monotonic ? V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC : V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN) |
                   (f.error ? V4L2_BUF_FLAG_ERROR : 0u);
        b->timestamp.tv_sec = f.time_ns / 1'000'000'000;
        b->timestamp.tv_usec = (f.time_ns % 1'000'000'000) / 1000;
        return 0;
      }
      default:
        return -ENOTTY;
    }
  }

  int mmap(int, std::size_t length, std::int64_t offset, void** address) override {
    const auto index = static_cast<std::size_t>(offset / 65536);
    if (index >= storage_.size() || length != storage_[index].size()) return -EINVAL;
    mapped_bytes += static_cast<long>(length);
    *address = storage_[index].data();
    return 0;
  }
  void munmap(void*, std::size_t length) override { mapped_bytes -= static_cast<long>(length); }

  int poll(int fd, short, int) override {
    if (fd - 100 <= gone_generation_ && !present_) return POLLERR | POLLHUP;
    return streaming && !frames.empty() ? POLLIN : 0;
  }

 private:
  std::vector<std::uint32_t> distinct_fourccs() const {
    std::vector<std::uint32_t> out;
    for (const auto& f : formats) {
      if (std::find(out.begin(), out.end(), f.fourcc) == out.end()) out.push_back(f.fourcc);
    }
    return out;
  }
  bool present_ = true;
  int generation_ = 0, gone_generation_ = -1;
  std::vector<std::vector<std::uint8_t>> storage_;
  std::deque<std::uint32_t> queued_;
};

class FakeNodes final : public VideoNodeDirectory {
 public:
  std::vector<VideoNode> nodes;
  std::vector<VideoNode> list() const override { return nodes; }
};

struct FakeClock {
  std::int64_t now = 1'000'000'000'000;
  V4l2Camera::Clock fn() {
    return [this] { return now; };
  }
};

std::shared_ptr<FakeV4l2Device> ir_camera() {
  auto d = std::make_shared<FakeV4l2Device>();
  d->formats = {{V4L2_PIX_FMT_MJPEG, 1280, 720, {30, 60}},
                {V4L2_PIX_FMT_YUYV, 640, 480, {30}},
                {V4L2_PIX_FMT_YUYV, 1280, 720, {10}},
                {V4L2_PIX_FMT_GREY, 320, 240, {120}},
                {V4L2_PIX_FMT_GREY, 640, 480, {120, 60}}};
  return d;
}

std::shared_ptr<FakeNodes> some_nodes() {
  auto n = std::make_shared<FakeNodes>();
  n->nodes = {{"/dev/video0", "UVC Camera (046d:0825)", 0, true, 0x046d, 0x0825, 1, 4},
              {"/dev/video1", "UVC Camera (046d:0825)", 1, true, 0x046d, 0x0825, 1, 4}};
  return n;
}

cv::Mat gradient(int w, int h) {
  cv::Mat m(h, w, CV_8UC1);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) m.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((x * 3 + y * 5) & 0xFF);
  return m;
}

std::vector<std::uint8_t> grey_bytes(const cv::Mat& m, std::uint32_t padding) {
  std::vector<std::uint8_t> out;
  for (int y = 0; y < m.rows; ++y) {
    out.insert(out.end(), m.ptr<std::uint8_t>(y), m.ptr<std::uint8_t>(y) + m.cols);
    out.insert(out.end(), padding, 0xEE);
  }
  return out;
}

std::string error_of(const std::function<void()>& f, CameraError::Kind* kind = nullptr) {
  try {
    f();
  } catch (const CameraError& e) {
    if (kind != nullptr) *kind = e.kind();
    return e.what();
  } catch (const std::exception& e) {
    return std::string("other exception: ") + e.what();
  }
  return "no error";
}

V4l2CameraOptions opts(const std::string& dev = "/dev/video0") {
  V4l2CameraOptions o;
  o.device = dev;
  return o;
}

}  // namespace

// ---- negotiation ----

TEST(V4l2Camera, PicksHighestRateThenGreyThenLargest) {
  auto dev = ir_camera();
  FakeClock clock;
  V4l2Camera cam(opts(), dev, some_nodes(), clock.fn());
  EXPECT_EQ(describe_mode(cam.mode()), "GREY 640x480@120");
  EXPECT_EQ(dev->format.fmt.pix.pixelformat, V4L2_PIX_FMT_GREY);
  EXPECT_EQ(dev->timeperframe.numerator, 1u);
  EXPECT_EQ(dev->timeperframe.denominator, 120u);
  EXPECT_TRUE(dev->streaming);
  const auto st = cam.status();
  EXPECT_TRUE(st.healthy);
  EXPECT_EQ(st.description, "camera:/dev/video0 640x480 GREY 120 fps (Fake IR Camera)");
  EXPECT_EQ(cam.supported_modes().size(), 7u);
}

TEST(V4l2Camera, HonoursWantedSizeAndRate) {
  std::vector<CameraMode> modes = {{V4L2_PIX_FMT_MJPEG, 1280, 720, 1, 30}, {V4L2_PIX_FMT_YUYV, 1280, 720, 1, 30},
                                   {V4L2_PIX_FMT_MJPEG, 1280, 720, 1, 60}, {V4L2_PIX_FMT_GREY, 640, 480, 1, 120}};
  V4l2CameraOptions o;
  o.width = 1280;
  o.height = 720;
  EXPECT_EQ(describe_mode(*choose_mode(modes, o)), "MJPG 1280x720@60");
  o.fps = 30;
  EXPECT_EQ(describe_mode(*choose_mode(modes, o)), "YUYV 1280x720@30");  // YUYV before MJPG at equal rate
  o.fps = 25;
  EXPECT_FALSE(choose_mode(modes, o));
  o = {};
  o.fps = 60;
  EXPECT_EQ(describe_mode(*choose_mode(modes, o)), "MJPG 1280x720@60");

  auto dev = ir_camera();
  auto o2 = opts();
  o2.width = 1280;
  o2.height = 720;
  o2.fps = 30;
  V4l2Camera cam(o2, dev, some_nodes());
  EXPECT_EQ(describe_mode(cam.mode()), "MJPG 1280x720@30");
  EXPECT_EQ(dev->timeperframe.denominator, 30u);
}

TEST(V4l2Camera, ModesWithoutListedIntervals) {
  auto dev = std::make_shared<FakeV4l2Device>();
  dev->formats = {{V4L2_PIX_FMT_YUYV, 640, 480, {}}};
  V4l2Camera cam(opts(), dev, some_nodes());
  EXPECT_EQ(describe_mode(cam.mode()), "YUYV 640x480");
  EXPECT_EQ(describe_modes(cam.supported_modes()), "YUYV 640x480");
}

// ---- conversion ----

TEST(V4l2Camera, GreyFramesWithLinePadding) {
  auto dev = ir_camera();
  dev->padding = 32;
  FakeClock clock;
  V4l2Camera cam(opts(), dev, some_nodes(), clock.fn());
  const cv::Mat img = gradient(640, 480);
  dev->frames.push_back({grey_bytes(img, 32), 0, 5'000'000'000});
  const auto f = cam.next(0);
  ASSERT_TRUE(f);
  ASSERT_EQ(f->image.type(), CV_8UC1);
  ASSERT_EQ(f->image.size(), img.size());
  EXPECT_EQ(cv::norm(f->image, img, cv::NORM_INF), 0.0);
}

TEST(V4l2Camera, YuyvKeepsTheLumaChannel) {
  auto dev = std::make_shared<FakeV4l2Device>();
  dev->formats = {{V4L2_PIX_FMT_YUYV, 64, 48, {30}}};
  V4l2Camera cam(opts(), dev, some_nodes());
  const cv::Mat img = gradient(64, 48);
  std::vector<std::uint8_t> yuyv;
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      yuyv.push_back(img.at<std::uint8_t>(y, x));
      yuyv.push_back(x % 2 == 0 ? 90 : 200);  // U, V: must not leak into the grey image
    }
  }
  dev->frames.push_back({yuyv, 0, 1'000});
  const auto f = cam.next(0);
  ASSERT_TRUE(f);
  EXPECT_EQ(cv::norm(f->image, img, cv::NORM_INF), 0.0);
}

TEST(V4l2Camera, MjpgIsDecodedToGrey) {
  auto dev = std::make_shared<FakeV4l2Device>();
  dev->formats = {{V4L2_PIX_FMT_MJPEG, 160, 120, {30}}};
  V4l2Camera cam(opts(), dev, some_nodes());
  cv::Mat img(120, 160, CV_8UC1, cv::Scalar(40));
  cv::rectangle(img, cv::Rect(40, 30, 60, 40), cv::Scalar(220), cv::FILLED);
  std::vector<std::uint8_t> jpeg;
  ASSERT_TRUE(cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, 95}));
  dev->frames.push_back({jpeg, 0, 1'000});
  dev->frames.push_back({{0x00, 0x01, 0x02}, 1, 2'000});  // corrupt: counted as dropped
  const auto f = cam.next(0);
  ASSERT_TRUE(f);
  ASSERT_EQ(f->image.type(), CV_8UC1);
  ASSERT_EQ(f->image.size(), img.size());
  EXPECT_LT(cv::norm(f->image, img, cv::NORM_L1) / static_cast<double>(img.total()), 3.0);
  EXPECT_FALSE(cam.next(0));
  EXPECT_EQ(cam.status().dropped, 1u);
  EXPECT_EQ(cam.status().frames, 1u);
}

// Issue 23 item 6: a frame declaring another size than the negotiated mode (a bomb declaring
// 20000x20000, or just a mismatch) is dropped before it is decoded.
TEST(V4l2Camera, MjpgFramesOfAnotherDeclaredSizeAreDroppedUndecoded) {
  auto dev = std::make_shared<FakeV4l2Device>();
  dev->formats = {{V4L2_PIX_FMT_MJPEG, 160, 120, {30}}};
  V4l2Camera cam(opts(), dev, some_nodes());
  std::vector<std::uint8_t> small, bomb;
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(60, 80, CV_8UC1, cv::Scalar(90)), small));
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(120, 160, CV_8UC1, cv::Scalar(90)), bomb));
  const auto header = read_image_header(bomb);
  ASSERT_TRUE(header);
  ASSERT_EQ(header->width, 160u);
  // Patch the frame header (SOF0: FF C0, length, precision, height, width) to 20000x20000.
  for (std::size_t i = 2; i + 9 < bomb.size(); ++i) {
    if (bomb[i] == 0xFF && bomb[i + 1] == 0xC0) {
      bomb[i + 5] = 20000 >> 8, bomb[i + 6] = 20000 & 0xFF, bomb[i + 7] = 20000 >> 8, bomb[i + 8] = 20000 & 0xFF;
      break;
    }
  }
  ASSERT_EQ(read_image_header(bomb)->width, 20000u);
  dev->frames.push_back({small, 0, 1'000});
  dev->frames.push_back({bomb, 1, 2'000});
  EXPECT_FALSE(cam.next(0));
  EXPECT_FALSE(cam.next(0));
  EXPECT_EQ(cam.status().dropped, 2u);
  EXPECT_EQ(cam.status().frames, 0u);
}

// ---- timestamps and drops ----

TEST(V4l2Camera, DriverTimestampsAndSequenceGaps) {
  auto dev = ir_camera();
  FakeClock clock;
  V4l2Camera cam(opts(), dev, some_nodes(), clock.fn());
  const auto bytes = grey_bytes(gradient(640, 480), 0);
  for (std::uint32_t s : {10u, 11u, 12u, 15u, 16u}) dev->frames.push_back({bytes, s, 7'000'000'000 + s * 8'333'000});
  dev->frames.push_back({bytes, 17, 7'000'000'000 + 17 * 8'333'000, true});  // flagged as damaged
  dev->frames.push_back({bytes, 18, 7'000'000'000 + 18 * 8'333'000});
  std::vector<EyeFrame> got;
  for (int i = 0; i < 10; ++i) {
    if (auto f = cam.next(0)) got.push_back(std::move(*f));
  }
  ASSERT_EQ(got.size(), 6u);
  EXPECT_EQ(got[0].time_ns, 7'000'000'000 + 10 * 8'333'000);  // the driver's time, not the clock's
  EXPECT_EQ(got[0].sequence, 10u);
  EXPECT_EQ(got[3].sequence, 15u);
  EXPECT_EQ(got[5].sequence, 18u);
  for (std::size_t i = 1; i < got.size(); ++i) EXPECT_GT(got[i].time_ns, got[i - 1].time_ns);
  EXPECT_EQ(cam.status().dropped, 3u);  // 13, 14 missing; 17 damaged
  EXPECT_EQ(cam.status().frames, 6u);
}

TEST(V4l2Camera, StampsOnArrivalWithoutMonotonicTimestamps) {
  auto dev = ir_camera();
  dev->monotonic = false;
  FakeClock clock;
  V4l2Camera cam(opts(), dev, some_nodes(), clock.fn());
  dev->frames.push_back({grey_bytes(gradient(640, 480), 0), 0, 42});
  clock.now = 9'000'000'000;
  const auto f = cam.next(0);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->time_ns, 9'000'000'000);
  const auto notes = cam.notes();
  EXPECT_TRUE(std::any_of(notes.begin(), notes.end(),
                          [](const std::string& n) { return n.find("no monotonic buffer timestamps") != n.npos; }));
}

TEST(V4l2Camera, TimesOutWithoutFrames) {
  auto dev = ir_camera();
  V4l2Camera cam(opts(), dev, some_nodes());
  EXPECT_FALSE(cam.next(0));
  EXPECT_TRUE(cam.status().healthy);
}

// ---- controls ----

TEST(V4l2Camera, SetsOfferedControlsAndReportsMissingOnes) {
  auto dev = ir_camera();
  dev->exposure = FakeControl{1, 5000, 156};
  auto o = opts();
  o.exposure = 9000;
  o.gain = 10;
  V4l2Camera cam(o, dev, some_nodes());
  EXPECT_EQ(dev->controls_set[V4L2_CID_EXPOSURE_AUTO], V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(dev->controls_set[V4L2_CID_EXPOSURE_ABSOLUTE], 5000);
  EXPECT_EQ(dev->controls_set.count(V4L2_CID_GAIN), 0u);
  std::string all;
  for (const auto& n : cam.notes()) all += n + "\n";
  EXPECT_NE(all.find("gain requested but the camera offers no such control"), std::string::npos) << all;
  EXPECT_NE(all.find("exposure_absolute 1..5000 (default 156), set 5000 (clamped from 9000)"), std::string::npos)
      << all;
}

// ---- start-up errors ----

TEST(V4l2Camera, MissingDeviceListsWhatIsPresent) {
  auto dev = ir_camera();
  CameraError::Kind kind{};
  const auto msg = error_of([&] { V4l2Camera cam(opts("/dev/video7"), dev, some_nodes()); }, &kind);
  EXPECT_EQ(kind, CameraError::Kind::missing);
  EXPECT_EQ(msg,
            "camera /dev/video7: no such device (video devices present: /dev/video0 (UVC Camera (046d:0825)), "
            "/dev/video1 (UVC Camera (046d:0825)))");
  const auto none = error_of([&] { V4l2Camera cam(opts("/dev/video7"), dev, std::make_shared<FakeNodes>()); });
  EXPECT_EQ(none, "camera /dev/video7: no such device (video devices present: none)");
}

TEST(V4l2Camera, BusyAtEachStepNamesTheDevice) {
  for (const unsigned long request : {VIDIOC_S_FMT, VIDIOC_REQBUFS, VIDIOC_STREAMON}) {
    auto dev = ir_camera();
    dev->fail[request] = EBUSY;
    CameraError::Kind kind{};
    const auto msg = error_of([&] { V4l2Camera cam(opts(), dev, some_nodes()); }, &kind);
    EXPECT_EQ(kind, CameraError::Kind::busy);
    EXPECT_NE(msg.find("camera /dev/video0 (Fake IR Camera) is busy (another program is using it"), std::string::npos)
        << msg;
    EXPECT_EQ(dev->open_fds, 0) << "file left open after " << msg;
    EXPECT_EQ(dev->mapped_bytes, 0);
  }
}

TEST(V4l2Camera, PermissionDeniedMentionsVideoGroupAndUdev) {
  auto dev = ir_camera();
  dev->open_error = EACCES;
  CameraError::Kind kind{};
  const auto msg = error_of([&] { V4l2Camera cam(opts(), dev, some_nodes()); }, &kind);
  EXPECT_EQ(kind, CameraError::Kind::permission);
  EXPECT_NE(msg.find("camera /dev/video0: permission denied"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'video' group"), std::string::npos) << msg;
  EXPECT_NE(msg.find("udev rule"), std::string::npos) << msg;
}

TEST(V4l2Camera, UnsupportedRequestListsSupportedModes) {
  auto dev = ir_camera();
  auto o = opts();
  o.width = 1920;
  o.height = 1080;
  o.fps = 60;
  CameraError::Kind kind{};
  const auto msg = error_of([&] { V4l2Camera cam(o, dev, some_nodes()); }, &kind);
  EXPECT_EQ(kind, CameraError::Kind::unsupported);
  EXPECT_EQ(msg,
            "camera /dev/video0 (Fake IR Camera): no GREY, YUYV or MJPG mode matches 1920x1080@60 fps; it supports: "
            "MJPG 1280x720@30, MJPG 1280x720@60, YUYV 640x480@30, YUYV 1280x720@10, GREY 320x240@120, "
            "GREY 640x480@120, GREY 640x480@60");
  EXPECT_EQ(dev->open_fds, 0);
}

TEST(V4l2Camera, UnreadableFormatsOnly) {
  auto dev = std::make_shared<FakeV4l2Device>();
  dev->formats = {{v4l2_fourcc('H', '2', '6', '4'), 1920, 1080, {30}}, {V4L2_PIX_FMT_NV12, 1920, 1080, {30}}};
  const auto msg = error_of([&] { V4l2Camera cam(opts(), dev, some_nodes()); });
  EXPECT_EQ(msg,
            "camera /dev/video0 (Fake IR Camera): offers no format fovea can read (fovea reads GREY, YUYV, MJPG); "
            "it supports: H264 1920x1080@30, NV12 1920x1080@30");
}

TEST(V4l2Camera, MetadataNodeIsNotACaptureDevice) {
  auto dev = ir_camera();
  dev->path = "/dev/video1";
  dev->caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
  CameraError::Kind kind{};
  const auto msg = error_of([&] { V4l2Camera cam(opts("/dev/video1"), dev, some_nodes()); }, &kind);
  EXPECT_EQ(kind, CameraError::Kind::not_capture);
  EXPECT_NE(msg.find("camera /dev/video1 (Fake IR Camera) is not a video capture device"), std::string::npos) << msg;
  EXPECT_NE(msg.find("/dev/video0 (UVC Camera (046d:0825))"), std::string::npos) << msg;
}

TEST(V4l2Camera, RealDeviceThatDoesNotExist) {
  CameraError::Kind kind{};
  const auto msg = error_of([&] { V4l2Camera cam(opts("/dev/video99")); }, &kind);
  EXPECT_EQ(kind, CameraError::Kind::missing) << msg;
  EXPECT_EQ(msg.rfind("camera /dev/video99: no such device (video devices present: ", 0), 0u) << msg;
  EXPECT_THROW(make_camera_source("camera:/dev/video99?fps=120"), CameraError);
}

// ---- run-time loss and recovery ----

TEST(V4l2Camera, SurvivesUnplugAndRecovers) {
  auto dev = ir_camera();
  FakeClock clock;
  V4l2Camera cam(opts(), dev, some_nodes(), clock.fn());
  const auto bytes = grey_bytes(gradient(640, 480), 0);
  dev->frames.push_back({bytes, 0, 1'000'000});
  dev->frames.push_back({bytes, 1, 2'000'000});
  ASSERT_TRUE(cam.next(0));
  ASSERT_TRUE(cam.next(0));

  dev->unplug();
  EXPECT_FALSE(cam.next(0));
  auto st = cam.status();
  EXPECT_FALSE(st.healthy);
  EXPECT_NE(st.problem.find("camera /dev/video0 (Fake IR Camera): device disconnected"), std::string::npos)
      << st.problem;
  EXPECT_NE(st.problem.find("retrying every 1 s"), std::string::npos) << st.problem;
  EXPECT_EQ(dev->open_fds, 0);
  EXPECT_EQ(dev->mapped_bytes, 0);

  const int attempts = dev->open_attempts;
  clock.now += 500'000'000;
  EXPECT_FALSE(cam.next(0));
  EXPECT_EQ(dev->open_attempts, attempts) << "retried before the interval passed";
  clock.now += 600'000'000;
  EXPECT_FALSE(cam.next(0));
  EXPECT_EQ(dev->open_attempts, attempts + 1);
  st = cam.status();
  EXPECT_FALSE(st.healthy);
  EXPECT_NE(st.problem.find("camera /dev/video0: no such device"), std::string::npos) << st.problem;

  dev->replug();
  dev->frames.push_back({bytes, 0, 9'000'000});  // the driver counts from 0 again
  dev->frames.push_back({bytes, 2, 9'500'000});
  clock.now += 1'000'000'000;
  const auto f = cam.next(0);
  ASSERT_TRUE(f);
  EXPECT_TRUE(cam.status().healthy);
  EXPECT_EQ(cam.status().problem, "");
  EXPECT_EQ(f->sequence, 2u) << "sequence continues across the re-open";
  const auto g = cam.next(0);
  ASSERT_TRUE(g);
  EXPECT_EQ(g->sequence, 4u);
  EXPECT_EQ(cam.status().dropped, 1u);
  EXPECT_EQ(cam.status().frames, 4u);
  EXPECT_EQ(cam.reconnects(), 1u);
  EXPECT_EQ(dev->opens, 2);
}

TEST(V4l2Camera, BusyOnReopenIsReportedAndRetried) {
  auto dev = ir_camera();
  FakeClock clock;
  V4l2Camera cam(opts(), dev, some_nodes(), clock.fn());
  dev->unplug();
  EXPECT_FALSE(cam.next(0));
  dev->replug();
  dev->fail[VIDIOC_STREAMON] = EBUSY;
  clock.now += 1'000'000'000;
  EXPECT_FALSE(cam.next(0));
  EXPECT_NE(cam.status().problem.find("is busy (another program is using it"), std::string::npos);
  dev->fail.clear();
  clock.now += 1'000'000'000;
  EXPECT_FALSE(cam.next(0));  // re-opened; no frame yet
  EXPECT_TRUE(cam.status().healthy);
}

TEST(V4l2Camera, CleansUpOnDestruction) {
  auto dev = ir_camera();
  {
    V4l2Camera cam(opts(), dev, some_nodes());
    EXPECT_GT(dev->mapped_bytes, 0);
  }
  EXPECT_EQ(dev->open_fds, 0);
  EXPECT_EQ(dev->mapped_bytes, 0);
  EXPECT_FALSE(dev->streaming);
}

TEST(V4l2Camera, ParsesSpecs) {
  const auto o = parse_camera_spec("camera:/dev/video2?width=640&height=480&fps=120&buffers=6&exposure=80&gain=3");
  EXPECT_EQ(o.device, "/dev/video2");
  EXPECT_EQ(o.width, 640u);
  EXPECT_EQ(o.height, 480u);
  EXPECT_EQ(o.fps, 120.0);
  EXPECT_EQ(o.buffers, 6u);
  EXPECT_EQ(o.exposure, 80);
  EXPECT_EQ(o.gain, 3);
  EXPECT_EQ(parse_camera_spec("camera:/dev/video0").buffers, 4u);
  EXPECT_THROW(parse_camera_spec("camera:"), std::invalid_argument);
  EXPECT_THROW(parse_camera_spec("video:/x"), std::invalid_argument);
  try {
    parse_camera_spec("camera:/dev/video0?fps=fast");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fps='fast' is not a frame rate in 0..10000"), std::string::npos) << e.what();
  }
  try {
    parse_camera_spec("camera:/dev/video0?colour=1");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown option 'colour' (allowed: width, height, fps"), std::string::npos);
  }
}

// ---- sysfs ----

namespace {
struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("fovea-devices-" + std::to_string(::getpid()) + "-" +
                                        std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};
void write_file(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text << "\n";
}
// A sysfs-like tree: class/video4linux/videoN -> devices/usbB/B-P/B-P:1.0/video4linux/videoN.
void add_usb_video_node(const fs::path& root, int n, int index, const std::string& vid, const std::string& pid,
                        int bus, int devnum, const std::string& port) {
  const fs::path usb = root / "devices" / port;
  write_file(usb / "idVendor", vid);
  write_file(usb / "idProduct", pid);
  write_file(usb / "busnum", std::to_string(bus));
  write_file(usb / "devnum", std::to_string(devnum));
  const fs::path node = usb / (port + ":1.0") / "video4linux" / ("video" + std::to_string(n));
  write_file(node / "name", "Eye Cam " + port);
  write_file(node / "index", std::to_string(index));
  fs::create_directory_symlink(usb / (port + ":1.0"), node / "device");
  fs::create_directories(root / "class");
  fs::create_directory_symlink(node, root / "class" / ("video" + std::to_string(n)));
}
}  // namespace

TEST(SysfsVideoNodes, MapsUsbIdsToCaptureNodes) {
  TempDir tmp;
  add_usb_video_node(tmp.path, 2, 0, "1234", "5678", 3, 7, "3-1");
  add_usb_video_node(tmp.path, 3, 1, "1234", "5678", 3, 7, "3-1");
  add_usb_video_node(tmp.path, 10, 0, "1234", "5678", 3, 9, "3-2");
  add_usb_video_node(tmp.path, 0, 0, "046d", "0825", 1, 4, "1-1");
  write_file(tmp.path / "class" / "video1" / "name", "vivid");  // not USB
  fs::create_directories(tmp.path / "class" / "vbi0");
  const auto nodes = std::make_shared<SysfsVideoNodes>((tmp.path / "class").string(), "/dev");
  const auto list = nodes->list();
  ASSERT_EQ(list.size(), 5u);
  EXPECT_EQ(list[0].path, "/dev/video0");
  EXPECT_EQ(list[0].vid, 0x046d);
  EXPECT_EQ(list[1].path, "/dev/video1");
  EXPECT_FALSE(list[1].usb);
  EXPECT_EQ(list[4].path, "/dev/video10");
  EXPECT_EQ(list[2].name, "Eye Cam 3-1");
  EXPECT_EQ(list[2].bus, 3);
  EXPECT_EQ(list[2].address, 7);
  EXPECT_EQ(find_video_node(*nodes, 0x1234, 0x5678), "/dev/video2");
  EXPECT_EQ(find_video_node(*nodes, 0x1234, 0x5678, 3, 9), "/dev/video10");
  EXPECT_EQ(find_video_node(*nodes, 0x046d, 0x0825), "/dev/video0");
  EXPECT_EQ(find_video_node(*nodes, 0xdead, 0xbeef), "");
  EXPECT_EQ(describe_video_nodes({}), "none");
}

// ---- video files ----

namespace {
fs::path write_test_video(const fs::path& dir, int frames, double fps) {
  const fs::path file = dir / "eye.avi";
  cv::VideoWriter w(file.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps, cv::Size(64, 48), true);
  EXPECT_TRUE(w.isOpened());
  for (int i = 0; i < frames; ++i) {
    cv::Mat img(48, 64, CV_8UC3, cv::Scalar(20, 20, 20));
    cv::circle(img, cv::Point(10 + i * 4, 24), 6, cv::Scalar(i * 20, 255 - i * 20, 128), cv::FILLED);
    w.write(img);
  }
  return file;
}
}  // namespace

TEST(VideoFileSource, ReadsEveryFrameWithIncreasingTimes) {
  TempDir tmp;
  const auto file = write_test_video(tmp.path, 10, 25);
  FakeClock clock;
  VideoFileSource src({file.string(), false}, clock.fn());
  EXPECT_NEAR(src.file_fps(), 25.0, 0.01);
  std::vector<EyeFrame> frames;
  while (auto f = src.next(0)) frames.push_back(std::move(*f));
  ASSERT_EQ(frames.size(), 10u);
  EXPECT_TRUE(src.ended());
  EXPECT_FALSE(src.next(0));
  EXPECT_EQ(frames[0].time_ns, clock.now);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].image.type(), CV_8UC1);
    EXPECT_EQ(frames[i].image.size(), cv::Size(64, 48));
    EXPECT_EQ(frames[i].sequence, i);
    if (i > 0) {
      EXPECT_GT(frames[i].time_ns, frames[i - 1].time_ns);
      EXPECT_NEAR(static_cast<double>(frames[i].time_ns - frames[i - 1].time_ns), 40e6, 1e6);
    }
  }
  EXPECT_EQ(src.status().frames, 10u);
  EXPECT_NE(src.status().description.find("video:eye.avi 64x48 25 fps"), std::string::npos)
      << src.status().description;
}

TEST(VideoFileSource, RealTimePacing) {
  TempDir tmp;
  const auto file = write_test_video(tmp.path, 6, 50);
  auto src = make_video_file_source("video:" + file.string(), true);
  const auto t0 = std::chrono::steady_clock::now();
  int n = 0;
  while (!src->ended()) {
    if (src->next(1000)) ++n;
  }
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(n, 6);
  EXPECT_GE(elapsed, 0.095);  // 5 frame periods of 20 ms after the first
  // A short timeout returns without a frame while the next one is not yet due.
  const auto file2 = write_test_video(tmp.path, 2, 2);
  VideoFileSource slow({file2.string(), true});
  ASSERT_TRUE(slow.next(0));
  EXPECT_FALSE(slow.next(5));
  EXPECT_FALSE(slow.ended());
}

TEST(VideoFileSource, ClearErrors) {
  TempDir tmp;
  const auto missing = (tmp.path / "nope.avi").string();
  try {
    VideoFileSource s({missing, false});
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "video file " + missing + ": no such file");
  }
  const auto junk = tmp.path / "junk.avi";
  write_file(junk, "this is not a video");
  try {
    VideoFileSource s({junk.string(), false});
    FAIL();
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("video file " + junk.string() + ": OpenCV ", 0), 0u) << msg;
    EXPECT_TRUE(msg.find("OpenCV cannot open it as a video (backends tried: ") != msg.npos ||
                msg.find("OpenCV opened it with backend ") != msg.npos)
        << msg;
  }
  if (::geteuid() != 0) {  // root reads anything
    const auto locked = write_test_video(tmp.path, 1, 25);
    fs::permissions(locked, fs::perms::none);
    try {
      VideoFileSource s({locked.string(), false});
      FAIL();
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(std::string(e.what()), "video file " + locked.string() + ": cannot be read (Permission denied)");
    }
  }
  EXPECT_THROW(make_video_file_source("video:", false), std::invalid_argument);
  EXPECT_THROW(make_video_file_source("camera:/dev/video0", false), std::invalid_argument);
}

// ---- USB hotplug ----

namespace {
class FakeUsbEnumerator final : public UsbEnumerator {
 public:
  explicit FakeUsbEnumerator(std::shared_ptr<std::vector<UsbDeviceInfo>> attached, std::shared_ptr<std::mutex> m)
      : attached_(std::move(attached)), mutex_(std::move(m)) {}
  std::vector<UsbDeviceInfo> devices() override {
    std::lock_guard lock(*mutex_);
    return *attached_;
  }
  void wait(int timeout_ms) override { std::this_thread::sleep_for(std::chrono::milliseconds(std::min(timeout_ms, 5))); }
  std::string mechanism() const override { return "fake"; }

 private:
  std::shared_ptr<std::vector<UsbDeviceInfo>> attached_;
  std::shared_ptr<std::mutex> mutex_;
};

struct Bus {
  std::shared_ptr<std::vector<UsbDeviceInfo>> attached = std::make_shared<std::vector<UsbDeviceInfo>>();
  std::shared_ptr<std::mutex> mutex = std::make_shared<std::mutex>();
  std::unique_ptr<UsbEnumerator> enumerator() { return std::make_unique<FakeUsbEnumerator>(attached, mutex); }
  void plug(UsbDeviceInfo d) {
    std::lock_guard lock(*mutex);
    attached->push_back(d);
  }
  void unplug(UsbDeviceInfo d) {
    std::lock_guard lock(*mutex);
    attached->erase(std::remove(attached->begin(), attached->end(), d), attached->end());
  }
};

// A frame source that logs its life and can be told to throw mid-read.
class LoggingSource final : public FrameSource {
 public:
  LoggingSource(std::vector<std::string>& log, std::string name) : log_(log), name_(std::move(name)) {
    log_.push_back("open " + name_);
  }
  ~LoggingSource() override { log_.push_back("close " + name_); }
  FrameSourceStatus status() const override { return {"fake " + name_, true, "", frames_, 0}; }
  std::optional<EyeFrame> next(int) override {
    if (throw_next) throw std::runtime_error("read error");
    ++frames_;
    return EyeFrame{cv::Mat(4, 4, CV_8UC1, cv::Scalar(1)), 1, frames_};
  }
  bool throw_next = false;

 private:
  std::vector<std::string>& log_;
  std::string name_;
  std::uint64_t frames_ = 0;
};

const KnownDevice kCam{0x1234, 0x5678, UsbDeviceKind::camera, "Eye Cam"};
const KnownDevice kHid{0x2104, 0x0127, UsbDeviceKind::hid, "Tobii"};
}  // namespace

TEST(UsbHotplug, ParsesKnownDeviceRows) {
  const auto d = parse_known_device("0x1234", "5678", "camera", "Eye Cam", "fovea.toml [[devices]] #1");
  EXPECT_EQ(d.vid, 0x1234);
  EXPECT_EQ(d.pid, 0x5678);
  EXPECT_EQ(d.kind, UsbDeviceKind::camera);
  EXPECT_EQ(usb_id(d.vid, d.pid), "1234:5678");
  EXPECT_EQ(parse_known_device("0x1", "0x2", "hid", "", "x").name, "0001:0002");
  try {
    parse_known_device("0x12345", "1", "camera", "", "fovea.toml [[devices]] #2");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()),
              "fovea.toml [[devices]] #2: vid = \"0x12345\" is not a USB id (1 to 4 hex digits, e.g. \"0x046d\")");
  }
  EXPECT_THROW(parse_known_device("1", "2", "tracker", "", "x"), std::invalid_argument);
}

TEST(UsbHotplug, WatcherReportsKnownArrivalsAndDeparturesOnly) {
  Bus bus;
  std::vector<std::string> events;
  UsbWatcher w(
      bus.enumerator(), {kCam, kHid},
      [&](const KnownDevice& k, const UsbDeviceInfo& d) { events.push_back("+" + k.name + "@" + std::to_string(d.address)); },
      [&](const KnownDevice& k, const UsbDeviceInfo& d) { events.push_back("-" + k.name + "@" + std::to_string(d.address)); });
  bus.plug({0x1234, 0x5678, 1, 5});
  bus.plug({0xaaaa, 0xbbbb, 1, 6});  // unknown: ignored
  w.poll();
  w.poll();  // no change, no events
  bus.plug({0x2104, 0x0127, 2, 3});
  bus.unplug({0x1234, 0x5678, 1, 5});
  bus.unplug({0xaaaa, 0xbbbb, 1, 6});
  w.poll();
  bus.plug({0x1234, 0x5678, 1, 8});  // back, at a new address
  w.poll();
  // Within one pass departures come first, so a replug is seen as close-then-open.
  EXPECT_EQ(events, (std::vector<std::string>{"+Eye Cam@5", "-Eye Cam@5", "+Tobii@3", "+Eye Cam@8"}));
  EXPECT_EQ(w.mechanism(), "fake");
}

TEST(UsbHotplug, SupervisorOpensClosesAndReopens) {
  Bus bus;
  std::vector<std::string> log;
  FakeClock clock;
  DeviceSupervisor sup(
      kCam, [&](const UsbDeviceInfo& d) { return std::make_unique<LoggingSource>(log, std::to_string(d.address)); },
      1000, clock.fn());
  UsbWatcher w(
      bus.enumerator(), {kCam, kHid},
      [&](const KnownDevice& k, const UsbDeviceInfo& d) { sup.on_arrival(k, d); },
      [&](const KnownDevice& k, const UsbDeviceInfo& d) { sup.on_departure(k, d); });

  w.poll();
  EXPECT_FALSE(sup.next(0));
  EXPECT_FALSE(sup.status().healthy);
  EXPECT_EQ(sup.status().problem, "waiting for Eye Cam (1234:5678) to be plugged in");

  bus.plug({0x2104, 0x0127, 1, 2});  // another known device: not ours
  bus.plug({0x1234, 0x5678, 1, 5});
  w.poll();
  ASSERT_TRUE(sup.next(0));
  ASSERT_TRUE(sup.next(0));
  EXPECT_TRUE(sup.is_open());
  EXPECT_TRUE(sup.status().healthy);
  EXPECT_EQ(sup.status().frames, 2u);

  bus.unplug({0x1234, 0x5678, 1, 5});
  w.poll();
  EXPECT_FALSE(sup.next(0));
  EXPECT_FALSE(sup.is_open());
  EXPECT_EQ(sup.status().problem, "Eye Cam (1234:5678) was unplugged; waiting for it to return");

  bus.plug({0x1234, 0x5678, 1, 9});
  w.poll();
  ASSERT_TRUE(sup.next(0));
  EXPECT_EQ(sup.status().frames, 3u);
  EXPECT_EQ(sup.opens(), 2u);
  EXPECT_EQ(log, (std::vector<std::string>{"open 5", "close 5", "open 9"}));
}

TEST(UsbHotplug, SupervisorRetriesWhileTheNodeIsNotReadyAndSurvivesThrowingReads) {
  std::vector<std::string> log;
  FakeClock clock;
  int failures = 2;
  LoggingSource* current = nullptr;
  DeviceSupervisor sup(
      kCam,
      [&](const UsbDeviceInfo&) -> std::unique_ptr<FrameSource> {
        if (failures-- > 0) throw std::runtime_error("no /dev/videoN node yet");
        auto s = std::make_unique<LoggingSource>(log, "cam");
        current = s.get();
        return s;
      },
      1000, clock.fn());
  sup.on_arrival(kCam, {0x1234, 0x5678, 1, 5});
  EXPECT_FALSE(sup.next(0));
  EXPECT_NE(sup.status().problem.find("is plugged in but cannot be opened: no /dev/videoN node yet"),
            std::string::npos);
  EXPECT_FALSE(sup.next(0));  // not yet due
  clock.now += 1'000'000'000;
  EXPECT_FALSE(sup.next(0));  // second failure
  clock.now += 1'000'000'000;
  ASSERT_TRUE(sup.next(0));
  current->throw_next = true;
  EXPECT_FALSE(sup.next(0));  // the read threw: closed, not crashed
  EXPECT_FALSE(sup.is_open());
  clock.now += 1'000'000'000;
  EXPECT_TRUE(sup.next(0));
  EXPECT_EQ(log, (std::vector<std::string>{"open cam", "close cam", "open cam"}));
}

TEST(UsbHotplug, CameraOpenerFindsTheNodeAndSurvivesUnplugMidStream) {
  TempDir tmp;
  add_usb_video_node(tmp.path, 4, 0, "1234", "5678", 2, 11, "2-1");
  auto nodes = std::make_shared<SysfsVideoNodes>((tmp.path / "class").string(), "/dev");
  auto dev = ir_camera();
  dev->path = "/dev/video4";
  FakeClock clock;
  DeviceSupervisor sup(kCam, camera_opener(V4l2CameraOptions{}, nodes, dev), 1000, clock.fn());
  sup.on_arrival(kCam, {0x1234, 0x5678, 2, 11});
  dev->frames.push_back({grey_bytes(gradient(640, 480), 0), 0, 5});
  const auto f = sup.next(0);
  ASSERT_TRUE(f);
  EXPECT_NE(sup.status().description.find("camera:/dev/video4 640x480 GREY 120 fps"), std::string::npos)
      << sup.status().description;
  // Unplugged mid-read: the camera sees ENODEV before the watcher reports the departure.
  dev->unplug();
  EXPECT_FALSE(sup.next(0));
  EXPECT_FALSE(sup.status().healthy);
  EXPECT_NE(sup.status().problem.find("device disconnected"), std::string::npos) << sup.status().problem;
  sup.on_departure(kCam, {0x1234, 0x5678, 2, 11});
  EXPECT_FALSE(sup.next(0));
  EXPECT_EQ(dev->open_fds, 0);
  dev->replug();  // back with a new USB address, as sysfs now says
  write_file(tmp.path / "devices" / "2-1" / "devnum", "12");
  sup.on_arrival(kCam, {0x1234, 0x5678, 2, 12});
  dev->frames.push_back({grey_bytes(gradient(640, 480), 0), 0, 6});
  EXPECT_TRUE(sup.next(0));
  EXPECT_EQ(sup.opens(), 2u);
}

TEST(UsbHotplug, WatcherThreadDeliversArrivals) {
  Bus bus;
  std::atomic<int> arrivals{0};
  UsbWatcher w(
      bus.enumerator(), {kCam}, [&](const KnownDevice&, const UsbDeviceInfo&) { ++arrivals; }, nullptr);
  w.start(10);
  bus.plug({0x1234, 0x5678, 1, 5});
  for (int i = 0; i < 400 && arrivals.load() == 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  w.stop();
  EXPECT_EQ(arrivals.load(), 1);
}

TEST(UsbHotplug, RealLibusbEnumeratorStartsOrSaysWhy) {
  // This machine may have no USB at all; either libusb starts (and lists whatever there is) or the
  // error says what is missing. Never a crash.
  try {
    auto e = make_libusb_enumerator();
    EXPECT_TRUE(e->mechanism() == "libusb hotplug" || e->mechanism() == "libusb polling") << e->mechanism();
    UsbWatcher w(std::move(e), {kCam}, nullptr, nullptr);
    w.poll();
    w.poll();
  } catch (const std::runtime_error& err) {
    EXPECT_EQ(std::string(err.what()).rfind("USB: libusb cannot start", 0), 0u) << err.what();
  }
}
