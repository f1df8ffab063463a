// SPDX-License-Identifier: Apache-2.0
// The viewer feed (fovea/protocol/viewer_feed.h, PROTOCOL.md §17): the messages' bytes (golden
// vectors), what a reader rejects, and the socket: frames reach a reader downscaled and no faster
// than the rate, nothing is copied while no reader listens, a reader that does not read misses
// frames without holding up the others or the loop, readers beyond the limit are turned away,
// statuses arrive, and the file has the mode asked for.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <numeric>
#include <string>
#include <thread>

#include "fovea/protocol/clock.h"
#include "fovea/protocol/viewer_feed.h"
#include "temp_dir.h"

using namespace fovea::protocol;

namespace {

struct TempDir : fovea::test::TempDir {
  TempDir() : fovea::test::TempDir("fovea-eyesock") {}
  std::string sock() const { return (path / "control-1-viewer.sock").string(); }
};

EyeFrameInfo sample_info() {
  EyeFrameInfo i;
  i.frame = 0x0102030405060708ULL;
  i.time_ns = 1'000'000'000;
  i.detect_ns = 250'000;
  i.flags = kEyeFramePupil | kEyeFrameGlint;
  i.source_width = 4;
  i.source_height = 2;
  i.pupil_x = 1.5f;
  i.pupil_y = 1.0f;
  i.pupil_major = 2.0f;
  i.pupil_minor = 1.0f;
  i.pupil_angle_deg = 90.0f;
  i.confidence = 0.5f;
  i.roi_width = 4;
  i.roi_height = 2;
  i.glint_count = 1;
  i.glint_x[0] = 3.25f;
  i.glint_y[0] = 0.5f;
  return i;
}

std::string hex(std::span<const std::uint8_t> b) {
  std::string s;
  char buf[3];
  for (std::uint8_t v : b) {
    std::snprintf(buf, sizeof buf, "%02x", v);
    s += buf;
  }
  return s;
}

bool wait_for(const std::function<bool()>& done, int ms = 3000) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return done();
}

}  // namespace

// PROTOCOL.md §17.3 prints these bytes: a reader in another language checks itself against them.
TEST(ViewerFeedCodec, GoldenVector) {
  const std::vector<std::uint8_t> pixels{0, 64, 128, 255, 1, 2, 3, 4};
  const std::vector<std::uint8_t> b = encode_eye_frame(sample_info(), 4, 2, pixels);
  ASSERT_EQ(b.size(), kEyeFrameHeaderSize + 8);
  EXPECT_EQ(hex(std::span(b).first(80)),
            "46564546010590000807060504030201"   // magic, version, flags, header size, frame
            "00ca9a3b00000000" "90d00300"        // time, detect time
            "04000200" "04000200"                // source 4x2, image 4x2
            "0000c03f0000803f000000400000803f" "0000b442"  // pupil x y major minor angle
            "0000003f"                           // confidence
            "00000000000000000000804000000040"   // roi
            "01000000");                         // one glint, reserved
  EXPECT_EQ(hex(std::span(b).subspan(80, 8)), "000050400000003f");  // glint (3.25, 0.5)
  EXPECT_EQ(hex(std::span(b).subspan(88, 56)), std::string(112, '0'));
  EXPECT_EQ(hex(std::span(b).last(8)), "004080ff01020304");

  std::string error;
  const auto m = decode_eye_frame(b, error);
  ASSERT_TRUE(m) << error;
  EXPECT_EQ(m->info, sample_info());
  EXPECT_EQ(m->width, 4);
  EXPECT_EQ(m->height, 2);
  EXPECT_EQ(m->pixels, pixels);
}

TEST(ViewerFeedCodec, ReaderRejectsWhatTheSpecRejects) {
  const std::vector<std::uint8_t> pixels(8, 7);
  const std::vector<std::uint8_t> good = encode_eye_frame(sample_info(), 4, 2, pixels);
  const auto rejects = [](std::vector<std::uint8_t> b, const std::string& why) {
    std::string error;
    EXPECT_FALSE(decode_eye_frame(b, error)) << why;
    EXPECT_NE(error.find(why), std::string::npos) << error;
  };
  // One byte changed at a time: offset, value, what the error names.
  const struct {
    std::size_t at;
    std::uint8_t value;
    const char* why;
  } bad_bytes[] = {{0, 'X', "magic"},        {4, 2, "version 2"},          {5, 0x10, "flag"},
                   {32, 0, "allowed 1..1024"}, {76, 9, "more than 8 glints"}, {78, 1, "reserved"},
                   {91, 0x3f, "unused glint"}};  // 32: width 0; 91: the second (unused) glint slot
  for (const auto& c : bad_bytes) {
    auto b = good;
    b[c.at] = c.value;
    rejects(b, c.why);
  }
  auto b = good;
  b.pop_back();
  rejects(b, "does not match");
  b = good;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(&b[56], &nan, 4);
  rejects(b, "non-finite");
  rejects(std::vector<std::uint8_t>(good.begin(), good.begin() + 100), "shorter");

  EyeFrameInfo i = sample_info();
  i.confidence = nan;
  EXPECT_THROW(encode_eye_frame(i, 4, 2, pixels), std::invalid_argument);
  EXPECT_THROW(encode_eye_frame(sample_info(), 4, 3, pixels), std::invalid_argument);
  EXPECT_THROW(encode_eye_frame(sample_info(), 2000, 1, std::vector<std::uint8_t>(2000)), std::invalid_argument);
}

TEST(ViewerFeedCodec, DaemonStatusGoldenVectorAndRejections) {
  const std::vector<std::uint8_t> b = encode_daemon_status(R"({"a":1})");
  EXPECT_EQ(hex(b), "465653540100070" "07b2261223a317d");
  std::string error;
  const auto m = decode_viewer_message(b, error);
  ASSERT_TRUE(m) << error;
  EXPECT_EQ(std::get<DaemonStatusMessage>(*m).json, R"({"a":1})");
  auto bad = b;
  bad.pop_back();
  EXPECT_FALSE(decode_viewer_message(bad, error));
  EXPECT_NE(error.find("does not match"), std::string::npos) << error;
  bad = b;
  bad[5] = 1;
  EXPECT_FALSE(decode_viewer_message(bad, error));
  EXPECT_NE(error.find("reserved"), std::string::npos) << error;
  bad = b;
  bad[9] = 0;
  EXPECT_FALSE(decode_viewer_message(bad, error));
  EXPECT_NE(error.find("NUL"), std::string::npos) << error;
  EXPECT_THROW(encode_daemon_status(std::string(kMaxStatusJson + 1, 'x')), std::invalid_argument);
  const std::vector<std::uint8_t> frame = encode_eye_frame(sample_info(), 4, 2, std::vector<std::uint8_t>(8));
  ASSERT_TRUE(decode_viewer_message(frame, error)) << error;
}

TEST(ViewerFeedServer, StatusesReachReadersAndOnlyTheNewestWaits) {
  TempDir dir;
  ViewerFeedServer server(dir.sock(), 0600);
  server.publish_status(R"({"ignored":true})");  // nobody listens: not kept
  ViewerFeedReader reader(dir.sock());
  ASSERT_TRUE(wait_for([&] { return server.readers() == 1; }));
  server.publish_status(R"({"n":1})");
  std::optional<ViewerMessage> m = reader.next(2000);
  ASSERT_TRUE(m);
  EXPECT_EQ(std::get<DaemonStatusMessage>(*m).json, R"({"n":1})");
  EXPECT_FALSE(reader.next(100));
  EXPECT_EQ(server.stats().statuses, 1u);
}

TEST(ViewerFeedCodec, SocketBesideTheControlSocket) {
  EXPECT_EQ(viewer_socket_for("/run/fovea/control-47800.sock"), "/run/fovea/control-47800-viewer.sock");
  EXPECT_EQ(viewer_socket_for("/tmp/ctl"), "/tmp/ctl-viewer");
}

TEST(ViewerFeedServer, FramesReachAReaderDownscaledAndRateLimited) {
  TempDir dir;
  ViewerFeedOptions o;
  o.max_rate_hz = 10;
  o.max_width = 320;
  o.max_height = 240;
  ViewerFeedServer server(dir.sock(), 0660, o);
  struct stat st {};
  ASSERT_EQ(::stat(dir.sock().c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);

  // A 640x480 frame whose left half is 0 and right half 200.
  std::vector<std::uint8_t> image(640 * 480);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) image[static_cast<std::size_t>(y * 640 + x)] = x < 320 ? 0 : 200;
  EyeFrameInfo info = sample_info();
  info.source_width = 640;
  info.source_height = 480;
  EXPECT_FALSE(server.wants(info.time_ns)) << "no reader: the loop copies nothing";
  server.offer(info, image.data(), 640, 480, 640);
  EXPECT_EQ(server.stats().offered, 0u);

  ViewerFeedReader reader(dir.sock());
  ASSERT_TRUE(wait_for([&] { return server.stats().readers == 1; }));
  // 50 frames 10 ms apart (0.5 s) at a 10 Hz limit: 5 go out.
  for (int k = 0; k < 50; ++k) {
    info.frame = static_cast<std::uint64_t>(k);
    info.time_ns = 1'000'000'000 + k * 10'000'000LL;
    // The sender may still be busy with the last frame: give it the time a real camera would.
    wait_for([&] { return server.stats().offered == server.stats().sent; }, 200);
    server.offer(info, image.data(), 640, 480, 640);
  }
  std::vector<EyeFrameMessage> got;
  while (auto m = reader.next(300)) got.push_back(std::get<EyeFrameMessage>(*m));
  ASSERT_EQ(got.size(), 5u);
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k].info.frame, 10 * k);
    EXPECT_EQ(got[k].width, 320);
    EXPECT_EQ(got[k].height, 240);
    EXPECT_EQ(got[k].info.source_width, 640);
    EXPECT_EQ(got[k].pixels[159], 0);
    EXPECT_EQ(got[k].pixels[160], 200);
    EXPECT_EQ(got[k].pixels[160 + 239 * 320], 200);
  }
  EXPECT_EQ(reader.rejected(), 0u);
}

TEST(ViewerFeedServer, AReaderThatDoesNotReadMissesFramesAndHoldsNobodyUp) {
  TempDir dir;
  ViewerFeedOptions o;
  o.max_rate_hz = 1000;  // a socket holds a few frames of 320x240 (the kernel caps its buffer)
  ViewerFeedServer server(dir.sock(), 0600, o);
  ViewerFeedReader idle(dir.sock());  // never reads
  ViewerFeedReader active(dir.sock());
  ASSERT_TRUE(wait_for([&] { return server.stats().readers == 2; }));
  std::vector<std::uint8_t> image(320 * 240, 9);
  EyeFrameInfo info = sample_info();
  std::size_t received = 0;
  std::int64_t worst_offer_ns = 0;
  for (int k = 0; k < 200; ++k) {
    info.time_ns = 1'000'000'000 + k * 2'000'000LL;
    info.frame = static_cast<std::uint64_t>(k);
    wait_for([&] { return server.wants(info.time_ns); }, 100);
    const std::int64_t t0 = monotonic_ns();
    server.offer(info, image.data(), 320, 240, 320);
    worst_offer_ns = std::max(worst_offer_ns, monotonic_ns() - t0);
    while (active.next(0)) ++received;
  }
  while (active.next(200)) ++received;
  const auto st = server.stats();
  EXPECT_EQ(received, st.offered) << "the reading reader misses nothing";
  EXPECT_GT(st.dropped, 0u) << "the idle reader's buffer filled";
  EXPECT_EQ(st.sent + st.dropped, 2 * st.offered);
  EXPECT_LT(worst_offer_ns, 50'000'000) << "offer() copies and returns; it never waits for a reader";
}

TEST(ViewerFeedServer, ReadersBeyondTheLimitAreTurnedAwayAndLeaversForgotten) {
  TempDir dir;
  ViewerFeedOptions o;
  o.max_readers = 2;
  ViewerFeedServer server(dir.sock(), 0600, o);
  {
    ViewerFeedReader a(dir.sock()), b(dir.sock());
    ASSERT_TRUE(wait_for([&] { return server.stats().readers == 2; }));
    ViewerFeedReader c(dir.sock());  // connects (the backlog accepts), then is closed by the server
    ASSERT_TRUE(wait_for([&] { return server.stats().refused == 1; }));
    EXPECT_FALSE(c.next(500));
    EXPECT_TRUE(c.closed());
  }
  EXPECT_TRUE(wait_for([&] { return server.stats().readers == 0; }));
  EXPECT_FALSE(server.wants(0));
}

TEST(ViewerFeedServer, LiveSocketIsNotReplacedAndMissingOneIsNamed) {
  TempDir dir;
  ViewerFeedServer server(dir.sock(), 0600);
  EXPECT_THROW(ViewerFeedServer(dir.sock(), 0600), std::runtime_error);
  try {
    ViewerFeedReader r((dir.path / "nothing.sock").string());
    FAIL() << "connected to nothing";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("nothing.sock"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not there"), std::string::npos) << e.what();
  }
}
