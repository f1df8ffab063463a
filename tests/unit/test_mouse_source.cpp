// SPDX-License-Identifier: Apache-2.0
// The mouse source (sources/mouse/mouse_source.h) on a real X server: run under
// deploy/with-xvfb.sh, which starts Xvfb and sets DISPLAY. The test moves the pointer itself.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <variant>

#include "fovea/protocol/clock.h"
#include "sources/mouse/mouse_source.h"

// Last: Xlib's macros.
#include <X11/Xlib.h>

namespace fovea::trackerd::mouse {
namespace {

protocol::GazeSample next_sample(MouseSource& m) {
  const auto item = m.next();
  EXPECT_TRUE(item);
  return item ? std::get<protocol::GazeSample>(*item) : protocol::GazeSample{};
}

TEST(MouseSource, ThePointerIsTheGaze) {
  ASSERT_NE(std::getenv("DISPLAY"), nullptr) << "run under deploy/with-xvfb.sh";
  Display* d = XOpenDisplay(nullptr);
  ASSERT_NE(d, nullptr);
  const int w = DisplayWidth(d, DefaultScreen(d)), h = DisplayHeight(d, DefaultScreen(d));
  MouseSource m(std::nullopt, std::nullopt, 200, protocol::monotonic_ns());
  EXPECT_EQ(m.display().width_px, static_cast<std::uint32_t>(w)) << "the X screen's size, when none is configured";
  for (const auto& [px, py] : {std::pair{100, 50}, std::pair{w - 1, h - 1}, std::pair{0, 0}}) {
    XWarpPointer(d, None, RootWindow(d, DefaultScreen(d)), 0, 0, 0, 0, px, py);
    XSync(d, False);
    const protocol::GazeSample s = next_sample(m);
    EXPECT_TRUE(s.flags & protocol::kGazeValid);
    EXPECT_NEAR(s.x, (px + 0.5) / w, 1e-6) << px;
    EXPECT_NEAR(s.y, (py + 0.5) / h, 1e-6) << py;  // y down, as the screen's
  }
  // Paced: ticks 5 ms apart at 200 Hz, stamped when read. One read may be late by up to a period
  // (a loaded machine) and the next on time, so the pace shows over many: 20 ticks after a sample
  // come at least 19 periods later, never faster than the rate.
  const protocol::GazeSample a = next_sample(m);
  protocol::GazeSample b = a;
  for (int i = 0; i < 20; ++i) {
    const protocol::GazeSample c = next_sample(m);
    EXPECT_GT(c.tracker_time_ns, b.tracker_time_ns);
    b = c;
  }
  EXPECT_GE(b.tracker_time_ns - a.tracker_time_ns, 19 * 5'000'000);
  EXPECT_NE(m.status_detail().find("pointer samples"), std::string::npos);
  // interrupt() wakes a waiting next() without a sample.
  MouseSource slow(std::nullopt, std::nullopt, 1, protocol::monotonic_ns() + 5'000'000'000);
  slow.interrupt();
  const std::int64_t before = protocol::monotonic_ns();
  EXPECT_FALSE(slow.next());
  EXPECT_LT(protocol::monotonic_ns() - before, 1'000'000'000);
  XCloseDisplay(d);
}

TEST(MouseSource, ClearErrors) {
  try {
    MouseSource m(std::string(":4711"), std::nullopt, 120, 0);
    ADD_FAILURE() << "opened a display that does not exist";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot open X display :4711"), std::string::npos) << e.what();
  }
  EXPECT_EQ(check_mouse_spec("mouse"), "");
  EXPECT_EQ(check_mouse_spec("mouse::1"), "");
  EXPECT_NE(check_mouse_spec("mouse:").find("expected mouse or mouse:DISPLAY"), std::string::npos);
  EXPECT_NE(check_mouse_spec("mousetrap").find("expected"), std::string::npos);
}

}  // namespace
}  // namespace fovea::trackerd::mouse
