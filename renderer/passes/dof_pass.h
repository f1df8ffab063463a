// SPDX-License-Identifier: Apache-2.0
#pragma once
// The dof pass as one object: its typed settings (parsed once per settings change, compared with a
// defaulted operator==) and what it keeps between frames (lee-mipmap's pyramid, the hidden and
// peeled layers it renders). It runs dof.method on the frame's G-buffer, or renders the scene again
// through the backend for the references (renderer/dof/DOF.md).
#include <cstdint>
#include <vector>

#include "backend/backend.h"
#include "dof/dof_image.h"
#include "dof/lee_mipmap.h"
#include "dof/lee_splat.h"
#include "dof/lens.h"
#include "pipeline/settings.h"

namespace fovea::render {

enum class DofMethod { Reference, Accum, LeeMipmap, LeeSplat, SchedlLayered };
DofMethod parse_dof_method(const std::string& name);
// The methods with a GPU implementation (GpuFrame), which runs where the frame's G-buffer lies:
// lee-mipmap (backend/gl/gl_lee_mipmap.h), schedl-layered (backend/gl/gl_schedl_layered.h) and
// lee-splat (backend/gl/gl_lee_splat.h), their peeled layers peeled there too. The references
// (reference, accum) render the scene again through the backend.
bool has_gpu_implementation(DofMethod method);

struct DofPassSettings {
  DofMethod method = DofMethod::LeeMipmap;
  dof::CocProjection projection = dof::CocProjection::Sensor;
  std::uint32_t samples = 0, layers = 1;  // the references' lens samples; schedl-layered's M
  std::uint64_t seed = 0;
  bool hidden = true;                     // lee-splat's hidden image where the backend peels
  dof::Aperture aperture = dof::Aperture::Disc;
  dof::LeeMipmapSettings mipmap;
  bool shadows = false;                   // for what it renders again
  bool operator==(const DofPassSettings&) const = default;
};
// dof.* and shadows.
DofPassSettings dof_pass_settings(const Settings& settings);
// lee-splat's settings from the pass's (the hidden image only where the backend peels).
dof::LeeSplatSettings lee_splat_settings(const DofPassSettings& d, bool backend_peels);

class DofPass {
 public:
  void set_settings(const DofPassSettings& s) { settings_ = s; }
  const DofPassSettings& settings() const { return settings_; }
  // The circle-of-confusion model of the scene's lens focused at focus_m (dof.projection).
  dof::CocModel coc_model(const Scene& scene, double focus_m) const;
  // The HDR colour with the lens focused at focus_m: from `g` (the frame's G-buffer at `time`, drawn
  // at `lod_levels`), or from the backend again (the references, the peeled layers).
  const dof::RgbImage& run(Backend& backend, const Scene& scene, const GBuffer& g,
                           const std::vector<std::uint8_t>& lod_levels, double focus_m, const FrameTime& time);
  const dof::RgbImage& color() const { return color_; }

 private:
  DofPassSettings settings_;
  dof::RgbImage color_;
  GBuffer hidden_;               // lee-splat's hidden image (the layer behind the visible surfaces)
  std::vector<GBuffer> peeled_;  // schedl-layered's depth-peeled layers behind the visible one
  dof::LeeMipmap lee_mipmap_;
};

}  // namespace fovea::render
