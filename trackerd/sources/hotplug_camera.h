// SPDX-License-Identifier: Apache-2.0
#pragma once
// `camera:usb:VID:PID[?options]`: an eye camera named by its USB identity rather than a /dev node.
// A libusb watcher (hotplug callbacks, or polling where the platform has none) reports arrivals
// and departures; the camera is opened when it is plugged in — also after the daemon started —,
// survives being unplugged, and is reopened when it returns.
#include <memory>
#include <string>
#include <vector>

#include "source_api/frame_source.h"
#include "sources/usb_hotplug.h"

namespace fovea::trackerd {

class HotplugCamera final : public FrameSource {
 public:
  // `known` is the configuration's device table; the wanted VID:PID is added if missing. Throws
  // std::invalid_argument for a bad spec, std::runtime_error when libusb cannot start.
  HotplugCamera(const std::string& spec, std::vector<KnownDevice> known);
  ~HotplugCamera() override;
  FrameSourceStatus status() const override;
  std::optional<EyeFrame> next(int timeout_ms) override { return supervisor_->next(timeout_ms); }

 private:
  std::unique_ptr<DeviceSupervisor> supervisor_;
  std::unique_ptr<UsbWatcher> watcher_;
  std::string mechanism_;
};

}  // namespace fovea::trackerd
