// SPDX-License-Identifier: Apache-2.0
#include "sources/hotplug_camera.h"

#include <stdexcept>

#include "sources/v4l2_camera.h"
#include "sources/v4l2_device.h"

namespace fovea::trackerd {

HotplugCamera::HotplugCamera(const std::string& spec, std::vector<KnownDevice> known) {
  // camera:usb:VID:PID[?options] -> the USB identity, and camera options for parse_camera_spec.
  const std::string prefix = "camera:usb:";
  const std::string rest = spec.substr(prefix.size());
  const auto query = rest.find('?');
  const std::string id = rest.substr(0, query);
  const auto colon = id.find(':');
  if (spec.rfind(prefix, 0) != 0 || colon == std::string::npos) {
    throw std::invalid_argument("--source " + spec + ": expected camera:usb:VID:PID[?options], e.g. camera:usb:046d:0825");
  }
  const KnownDevice wanted = parse_known_device(id.substr(0, colon), id.substr(colon + 1), "camera", "", "--source " + spec);
  const V4l2CameraOptions options =
      parse_camera_spec("camera:/dev/video0" + (query == std::string::npos ? std::string() : rest.substr(query)));
  bool listed = false;
  for (const auto& k : known) listed |= k.vid == wanted.vid && k.pid == wanted.pid;
  if (!listed) known.push_back(wanted);
  supervisor_ = std::make_unique<DeviceSupervisor>(wanted, camera_opener(options, std::make_shared<SysfsVideoNodes>()));
  DeviceSupervisor* sup = supervisor_.get();
  watcher_ = std::make_unique<UsbWatcher>(
      make_libusb_enumerator(), std::move(known),
      [sup](const KnownDevice& k, const UsbDeviceInfo& d) { sup->on_arrival(k, d); },
      [sup](const KnownDevice& k, const UsbDeviceInfo& d) { sup->on_departure(k, d); });
  mechanism_ = watcher_->mechanism();
  watcher_->start(1000);
}

HotplugCamera::~HotplugCamera() {
  if (watcher_) watcher_->stop();  // no callbacks into the supervisor once we start tearing down
}

FrameSourceStatus HotplugCamera::status() const {
  FrameSourceStatus s = supervisor_->status();
  s.description += " (" + mechanism_ + ")";
  return s;
}

}  // namespace fovea::trackerd
