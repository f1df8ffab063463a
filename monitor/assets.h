// SPDX-License-Identifier: Apache-2.0
#pragma once
// The page's files (monitor/web/), compiled in at build time (embed_assets.cmake): the monitor
// needs no files beside it and no network (no CDN).
#include <vector>

#include "web_server.h"

namespace fovea::monitor {

std::vector<Asset> page_assets();

}  // namespace fovea::monitor
