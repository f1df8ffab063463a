// SPDX-License-Identifier: Apache-2.0
#include "passes/dof_pass.h"

#include <cmath>

#include "dof/reference.h"
#include "dof/schedl_layered.h"

namespace fovea::render {

DofMethod parse_dof_method(const std::string& name) {
  return name == "reference"        ? DofMethod::Reference
         : name == "accum"          ? DofMethod::Accum
         : name == "lee-splat"      ? DofMethod::LeeSplat
         : name == "schedl-layered" ? DofMethod::SchedlLayered
                                    : DofMethod::LeeMipmap;
}

bool has_gpu_implementation(DofMethod method) {
  return method == DofMethod::LeeMipmap || method == DofMethod::SchedlLayered || method == DofMethod::LeeSplat;
}

dof::LeeSplatSettings lee_splat_settings(const DofPassSettings& d, bool backend_peels) {
  dof::LeeSplatSettings s;
  // The hidden image H (Lee §5.1.2): a second render, peeled by object, where the backend peels.
  s.use_hidden = d.hidden && backend_peels;
  s.aperture = d.aperture;
  return s;
}

DofPassSettings dof_pass_settings(const Settings& s) {
  DofPassSettings d;
  d.method = parse_dof_method(s.text("dof.method"));
  d.projection = s.is("dof.projection", "display") ? dof::CocProjection::Display : dof::CocProjection::Sensor;
  d.samples = static_cast<std::uint32_t>(std::lround(s.number("dof.samples")));
  d.layers = static_cast<std::uint32_t>(std::lround(s.number("dof.layers")));
  d.seed = static_cast<std::uint64_t>(s.number("dof.seed"));
  d.hidden = s.flag("dof.hidden");
  const std::string& aperture = s.text("dof.aperture");
  d.aperture = aperture == "gaussian"  ? dof::Aperture::Gaussian
               : aperture == "hexagon" ? dof::Aperture::Hexagon
                                       : dof::Aperture::Disc;
  d.mipmap.anisotropic = s.flag("dof.anisotropic");
  d.mipmap.smooth_foreground = s.flag("dof.smooth_foreground");
  d.mipmap.dob_per_coc = s.number("dof.sigma_per_coc");
  d.shadows = s.flag("shadows");
  return d;
}

dof::CocModel DofPass::coc_model(const Scene& scene, double focus_m) const {
  return dof::coc_model(scene.camera, scene.display, focus_m, settings_.projection);
}

const dof::RgbImage& DofPass::run(Backend& backend, const Scene& scene, const GBuffer& g,
                                  const std::vector<std::uint8_t>& lod_levels, double focus_m, const FrameTime& time) {
  const DofPassSettings& d = settings_;
  if (d.method == DofMethod::Reference || d.method == DofMethod::Accum) {
    BackendSettings bs;
    bs.shadows = d.shadows;
    bs.keep_frame = true;  // the frame's G-buffer (the overlay's ids where it lies on the GPU) stays
    dof::DofReference ref(backend, time, bs, scene.camera.lens, focus_m,
                          d.method == DofMethod::Reference ? dof::ReferenceKind::RayTraced
                                                           : dof::ReferenceKind::Accumulation,
                          d.seed);
    ref.add_samples(d.samples);
    color_ = ref.image();
    return color_;
  }
  dof::DofInput in;
  in.width = g.width;
  in.height = g.height;
  in.color = g.color.data();
  in.depth = g.depth.data();
  in.coc = coc_model(scene, focus_m);
  const bool peels = backend.capabilities().peeling;
  if (d.method == DofMethod::SchedlLayered) {
    // M depth-peeled layers where the backend peels (both do; a backend that cannot: M = 1).
    const std::uint32_t m = peels ? d.layers : 1u;
    peeled_.resize(m > 0 ? m - 1 : 0);
    BackendSettings bs;
    bs.shadows = d.shadows;
    bs.lod_levels = lod_levels;
    backend.render_peeled_layers(time, bs, peeled_);
    std::vector<dof::PeeledLayer> layers;
    for (const GBuffer& p : peeled_) layers.push_back({p.color.data(), p.depth.data()});
    dof::schedl_layered(in, layers, dof::SchedlSettings{}, color_);
    return color_;
  }
  if (d.method == DofMethod::LeeSplat) {
    const dof::LeeSplatSettings s = lee_splat_settings(d, peels);
    if (s.use_hidden) {
      BackendSettings bs;
      bs.shadows = d.shadows;
      bs.peel = 1;
      bs.lod_levels = lod_levels;
      backend.render(time, bs, hidden_);
      in.hidden_color = hidden_.color.data();
      in.hidden_depth = hidden_.depth.data();
    }
    dof::lee_splat(in, s, color_);
    return color_;
  }
  lee_mipmap_.run(in, d.mipmap, color_);
  return color_;
}

}  // namespace fovea::render
