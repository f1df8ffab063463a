// SPDX-License-Identifier: Apache-2.0
// Depth of field, accuracy versus time (issue step 7): every method x mean CoC x scene against the
// thin-lens distributed-ray-tracing reference (renderer/dof/reference.h), at 1024x768 by default.
//
// Scenes (the three cases, from the bundled scene files):
//   background-blur    attention.json focused on the nearest foreground object (2.9 m): the far
//                      scene blurs behind sharp objects (intensity leakage at their outlines).
//   foreground-blur    attention.json focused at 14 m: the near objects blur in front of a sharp
//                      far scene (blurring discontinuity at their outlines).
//   partial-occlusion  occlusion.json: thin bars 1 m away blur over a checkerboard in focus at 6 m.
// --scene FILE measures on any scene load_scene reads (.json, .gltf, .glb; e.g. the textured glTF
// stand-in) from its own camera at --size, in place of these: "<stem>-near-focus" focused at the 10th
// percentile of the pinhole G-buffer's depth over the pixels that hit geometry (the far scene blurs,
// like background-blur) and "<stem>-far-focus" at the 90th (the near scene blurs, like
// foreground-blur). Percentiles, not fixed distances, because the file's depth range is not known in
// advance; --focus-m A,B,... gives explicit distances instead ("<stem>-focus-<A>m").
// The aperture is scaled so that the mean CoC over the image's pixels is the row's CoC (4..64 px).
//
// Per row: PSNR (RGB) and SSIM (luma, Wang et al. 2004, 11x11 Gaussian window, sigma 1.5) of the
// method's tone-mapped image against the reference's, ms/frame (median of --repeats), and the two
// failure modes the papers name, as RMSE (8-bit levels) over the pixels where they show:
//   leak   background pixels (behind the focal plane, C > 2 px) within C/2 of an in-focus pixel
//          (C < 1 px): where a focused object's colour would leak into the blur (Lee §4.2);
//   edge   pixels within the foreground's mean C/2 of a blurred foreground pixel (in front, C > 2):
//          the blurred foreground boundary (Lee §4.3, Schedl & Wimmer's partial occlusion);
// and PSNR over the interior, where no depth discontinuity is within reach (interior_mask): there
// every one-layer method's lens model is exact, so what is left is its blur kernel's error.
//
// The "... gl" rows run the method's OpenGL implementation (backend/gl/gl_lee_mipmap.h,
// gl_schedl_layered.h, gl_lee_splat.h: on the ray tracer's peeled layers, the peeling not timed) on the same
// G-buffer through EGL (llvmpipe here, a GPU where there is one): ms/frame is the wall time with the
// upload and the readback a GPU-resident frame does not do; gpu_ms the passes alone (timestamp
// queries), and vs_cpu_db the PSNR of the GL image against the CPU implementation's. The "... gl
// compute" rows are the same with the compute passes (OpenGL 4.3: lee-mipmap's passes, schedl-layered's
// box blurs; frame.effect_passes), where the context has them. The CSV's
// device column names where each row ran ("cpu", or the OpenGL renderer): bench/make_fronts.py
// builds the governor's per-device fronts from it.
//
// The gap to the papers' figures (Lee's 37.66 / 35.41 dB for lee-mipmap) is split by two more tools:
// --aperture-sigma S renders the reference through Lee §4.1.3's Gaussian lens (blur deviation S x C,
// backend/lens_sample.h) instead of the real lens's uniform disc; the "gaussian gather" rows are the
// exact filter lee-mipmap approximates (dof/gaussian_gather.h), and vs_gather_db is each CPU
// lee-mipmap row's PSNR against the gather of its own sigma: the mipmap's own error.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "backend/embree/embree_backend.h"
#include "backend/gl/gl_backend.h"
#include "backend/gl/gl_lee_mipmap.h"
#include "backend/gl/gl_lee_splat.h"
#include "backend/gl/gl_schedl_layered.h"
#include "dof/gaussian_gather.h"
#include "dof/lee_mipmap.h"
#include "dof/lee_splat.h"
#include "dof/lens.h"
#include "dof/reference.h"
#include "dof/schedl_layered.h"
#include "image/image.h"
#include "passes/tonemap.h"
#include "scene/scene_loader.h"

using namespace fovea::render;
using namespace fovea::render::dof;
using Clock = std::chrono::steady_clock;

namespace {

struct Case {
  std::string name, file;
  double focus_m;
  // >= 0: focus_m is this percentile (0..1) of the pinhole depth over the pixels that hit geometry,
  // known only once the G-buffer is rendered (the --scene cases).
  double focus_percentile = -1;
};

// The p-th percentile (0..1, nearest rank) of the depth over the pixels that hit geometry; NaN when
// none does. A miss holds the far plane's depth (a finite number, not infinity), so hits are told
// apart by their object id (0 where nothing is hit).
double hit_depth_percentile(const GBuffer& g, double p) {
  std::vector<float> d;
  for (std::size_t i = 0; i < g.size(); ++i) {
    if (g.object_id[i] != 0 && std::isfinite(g.depth[i])) d.push_back(g.depth[i]);
  }
  if (d.empty()) return std::nan("");
  const auto k = static_cast<std::size_t>(std::lround(p * static_cast<double>(d.size() - 1)));
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(k), d.end());
  return d[k];
}

Image8 to_ldr(const RgbImage& hdr, std::uint32_t w, std::uint32_t h) {
  TonemapParams p;
  p.exact = true;
  Image8 out;
  tonemap(hdr, w, h, p, out);
  return out;
}

cv::Mat as_mat(const Image8& img) {
  return cv::Mat(static_cast<int>(img.height), static_cast<int>(img.width), CV_8UC3,
                 const_cast<std::uint8_t*>(img.rgb.data()))
      .clone();
}

double psnr(const cv::Mat& a, const cv::Mat& b) {
  const double mse = cv::norm(a, b, cv::NORM_L2SQR) / (static_cast<double>(a.total()) * a.channels());
  return mse <= 1e-12 ? 99.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

double ssim(const cv::Mat& a_rgb, const cv::Mat& b_rgb) {
  cv::Mat a, b;
  cv::cvtColor(a_rgb, a, cv::COLOR_RGB2GRAY);
  cv::cvtColor(b_rgb, b, cv::COLOR_RGB2GRAY);
  a.convertTo(a, CV_64F);
  b.convertTo(b, CV_64F);
  const double c1 = (0.01 * 255) * (0.01 * 255), c2 = (0.03 * 255) * (0.03 * 255);
  const auto blur = [](const cv::Mat& m) {
    cv::Mat o;
    cv::GaussianBlur(m, o, cv::Size(11, 11), 1.5);
    return o;
  };
  const cv::Mat mu_a = blur(a), mu_b = blur(b);
  const cv::Mat aa = blur(a.mul(a)) - mu_a.mul(mu_a), bb = blur(b.mul(b)) - mu_b.mul(mu_b);
  const cv::Mat ab = blur(a.mul(b)) - mu_a.mul(mu_b);
  cv::Mat num = (2 * mu_a.mul(mu_b) + c1).mul(2 * ab + c2);
  cv::Mat den = (mu_a.mul(mu_a) + mu_b.mul(mu_b) + c1).mul(aa + bb + c2);
  cv::Mat s;
  cv::divide(num, den, s);
  return cv::mean(s)[0];
}

double masked_rmse(const cv::Mat& a, const cv::Mat& b, const cv::Mat& mask) {
  if (cv::countNonZero(mask) == 0) return std::nan("");
  cv::Mat d;
  cv::absdiff(a, b, d);
  d.convertTo(d, CV_64FC3);
  d = d.mul(d);
  const cv::Scalar m = cv::mean(d, mask);
  return std::sqrt((m[0] + m[1] + m[2]) / 3.0);
}

struct Masks {
  cv::Mat leak, edge, interior;
  double mean_coc = 0;
};

// Pixels that no depth discontinuity reaches: a discontinuity is a pixel whose signed CoC differs
// from a 4-neighbour's by more than 1 px, its reach 1.5 x the larger CoC diameter of the two sides
// (3 deviations of a sigma = C / 2 Gaussian, beyond a disc's C / 2); a pixel is interior when it is
// farther than 1.5 x its own CoC and than the nearest discontinuity's reach. There a one-layer
// gather is the exact lens model, so the error left is the method's blur alone.
cv::Mat interior_mask(const cv::Mat& b) {
  const int w = b.cols, h = b.rows;
  cv::Mat not_disc(h, w, CV_8U, cv::Scalar(255)), reach(h, w, CV_32F, cv::Scalar(0.0f));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float v = b.at<float>(y, x);
      float far = 0;
      const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
      for (int k = 0; k < 4; ++k) {
        if (nx[k] < 0 || ny[k] < 0 || nx[k] >= w || ny[k] >= h) continue;
        const float u = b.at<float>(ny[k], nx[k]);
        if (std::fabs(u - v) > 1.0f) far = std::max({far, std::fabs(u), std::fabs(v)});
      }
      if (far > 0) {
        not_disc.at<std::uint8_t>(y, x) = 0;
        reach.at<float>(y, x) = 1.5f * far;
      }
    }
  }
  cv::Mat dist, labels;
  cv::distanceTransform(not_disc, dist, labels, cv::DIST_L2, 5, cv::DIST_LABEL_PIXEL);
  // Label k (from 1) is the k-th zero pixel of not_disc in row-major order.
  std::vector<float> reach_of_label(1, 0.0f);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (not_disc.at<std::uint8_t>(y, x) == 0) reach_of_label.push_back(reach.at<float>(y, x));
    }
  }
  cv::Mat inside = cv::Mat::zeros(h, w, CV_8U);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const auto label = static_cast<std::size_t>(labels.at<int>(y, x));
      const float near = label < reach_of_label.size() ? reach_of_label[label] : 0.0f;
      const float d = dist.at<float>(y, x);
      if (d > 1.5f * std::fabs(b.at<float>(y, x)) && d > near) inside.at<std::uint8_t>(y, x) = 255;
    }
  }
  return inside;
}
Masks failure_masks(const GBuffer& g, const CocModel& coc) {
  const int w = static_cast<int>(g.width), h = static_cast<int>(g.height);
  cv::Mat c(h, w, CV_32F), b(h, w, CV_32F);
  double sum = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double s = coc.signed_coc_px(static_cast<double>(g.depth[g.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y))]));
      b.at<float>(y, x) = static_cast<float>(s);
      c.at<float>(y, x) = static_cast<float>(std::fabs(s));
      sum += std::fabs(s);
    }
  }
  Masks m;
  m.mean_coc = sum / (static_cast<double>(w) * h);
  m.interior = interior_mask(b);
  // Distance (px) to the nearest in-focus pixel, and to the nearest blurred foreground pixel.
  cv::Mat not_focused = c >= 1.0f, not_foreground = b > -2.0f, dist_focus, dist_fg;
  cv::distanceTransform(not_focused, dist_focus, cv::DIST_L2, 3);
  cv::distanceTransform(not_foreground, dist_fg, cv::DIST_L2, 3);
  double fg_sum = 0;
  int fg_n = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (b.at<float>(y, x) < -2.0f) {
        fg_sum -= static_cast<double>(b.at<float>(y, x));
        ++fg_n;
      }
    }
  }
  const float fg_radius = fg_n > 0 ? static_cast<float>(fg_sum / fg_n / 2) : 0.0f;
  m.leak = cv::Mat::zeros(h, w, CV_8U);
  m.edge = cv::Mat::zeros(h, w, CV_8U);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float cb = b.at<float>(y, x);
      if (cb > 2.0f && dist_focus.at<float>(y, x) <= 0.5f * cb) m.leak.at<std::uint8_t>(y, x) = 255;
      if (fg_n > 0 && dist_fg.at<float>(y, x) <= fg_radius) m.edge.at<std::uint8_t>(y, x) = 255;
    }
  }
  return m;
}

double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Depth of field: PSNR, SSIM, failure modes and ms/frame of every method against the thin-lens "
               "ray-traced reference, per scene and mean CoC"};
  std::string size_text = "1024x768", csv_path, png_dir, cocs_text = "4,8,16,32,64", cases_text = "all";
  std::string methods_text = "all", scene_path, focus_text;
  std::uint32_t samples = 256, repeats = 5;
  std::uint32_t convergence = 0;
  double aperture_sigma = 0;
  app.add_option("--size", size_text, "image size WxH");
  app.add_option("--cocs", cocs_text, "mean CoC diameters in pixels, comma-separated");
  app.add_option("--cases", cases_text,
                 "the built-in cases: background-blur,foreground-blur,partial-occlusion or all (with --scene: all only)");
  app.add_option("--scene", scene_path,
                 "measure on this scene file (.json, .gltf or .glb, from its own camera at --size) instead of the built-in "
                 "cases: <stem>-near-focus focused at the 10th percentile of the pinhole depth over the pixels that hit "
                 "geometry, <stem>-far-focus at the 90th");
  app.add_option("--focus-m", focus_text,
                 "with --scene: these focus distances in metres, comma-separated, instead of the two percentiles "
                 "(cases <stem>-focus-<A>m)");
  app.add_option("--samples", samples, "reference lens samples per pixel (power of two: stratified)")
      ->check(CLI::Range(1u, 65536u));
  app.add_option("--repeats", repeats, "timed runs per method (median)")->check(CLI::Range(1u, 100u));
  app.add_option("--convergence", convergence,
                 "also measure the reference's own convergence: RMSE of 4..N/4 samples against N samples on the "
                 "first case at the largest CoC (N = this value; 0: skip)");
  app.add_option("--methods", methods_text,
                 "comma-separated method names to run (a name selects every row that starts with it, e.g. lee-mipmap), "
                 "or all (all but the gaussian gather rows, the exact filter lee-mipmap approximates: name them)");
  app.add_option("--aperture-sigma", aperture_sigma,
                 "the reference's aperture: 0 the real lens's uniform disc; S > 0 Lee's Gaussian lens, whose blur has a "
                 "per-axis deviation of S x the CoC diameter (0.5: Lee's sigma = C / 2)")
      ->check(CLI::Range(0.0, 4.0));
  app.add_option("--csv", csv_path, "write the table as CSV");
  app.add_option("--png", png_dir, "write every image (reference and methods) as PNG into this directory");
  CLI11_PARSE(app, argc, argv);

  unsigned w = 0, h = 0;
  if (std::sscanf(size_text.c_str(), "%ux%u", &w, &h) != 2 || w == 0 || h == 0 || w > 8192 || h > 8192) {
    std::cerr << "--size " << size_text << ": expected WxH, each 1..8192\n";
    return 2;
  }
  std::vector<double> cocs;
  {
    std::stringstream ss(cocs_text);
    std::string item;
    while (std::getline(ss, item, ',')) {
      char* end = nullptr;
      const double v = std::strtod(item.c_str(), &end);
      if (end == item.c_str() || *end != '\0' || !(v > 0) || v > 512) {
        std::cerr << "--cocs: '" << item << "' is not a CoC in (0, 512] px\n";
        return 2;
      }
      cocs.push_back(v);
    }
  }
  std::vector<std::string> method_filter;
  if (methods_text != "all") {
    std::stringstream ss(methods_text);
    std::string item;
    while (std::getline(ss, item, ',')) method_filter.push_back(item);
  }
  // The gaussian gather rows are an analysis tool (seconds per image): only when --methods names them.
  const auto method_selected = [&](const std::string& name) {
    if (method_filter.empty()) return name.rfind("gaussian gather", 0) != 0;
    return std::any_of(method_filter.begin(), method_filter.end(),
                       [&](const std::string& f) { return name.rfind(f, 0) == 0; });
  };
  // The bundled scenes: FOVEA_SOURCE_DIR in the environment (a copy of the tree elsewhere, as on the
  // device machine), else the tree this was built from.
  const char* env_src = std::getenv("FOVEA_SOURCE_DIR");
  const std::string src = env_src != nullptr && *env_src != '\0' ? env_src : FOVEA_SOURCE_DIR;
  std::vector<Case> cases = {{"background-blur", src + "/renderer/scenes/attention.json", 2.9},
                             {"foreground-blur", src + "/renderer/scenes/attention.json", 14.0},
                             {"partial-occlusion", src + "/renderer/scenes/occlusion.json", 6.0}};
  if (!focus_text.empty() && scene_path.empty()) {
    std::cerr << "--focus-m needs --scene (the built-in cases have their own focus distances)\n";
    return 2;
  }
  if (!scene_path.empty()) {
    // A user's scene: its depth range is unknown, so the focus is a depth percentile unless given.
    if (cases_text != "all") {
      std::cerr << "--cases " << cases_text << " with --scene: --cases selects among the built-in cases, --scene "
                << "replaces them; drop one of the two\n";
      return 2;
    }
    const std::string stem = std::filesystem::path(scene_path).stem().string();
    cases.clear();
    if (focus_text.empty()) {
      cases.push_back({stem + "-near-focus", scene_path, 0, 0.10});
      cases.push_back({stem + "-far-focus", scene_path, 0, 0.90});
    } else {
      std::stringstream ss(focus_text);
      std::string item;
      while (std::getline(ss, item, ',')) {
        char* end = nullptr;
        const double v = std::strtod(item.c_str(), &end);
        if (end == item.c_str() || *end != '\0' || !(v > 0) || !std::isfinite(v)) {
          std::cerr << "--focus-m: '" << item << "' is not a distance > 0 m\n";
          return 2;
        }
        char name[64];
        std::snprintf(name, sizeof name, "-focus-%gm", v);
        cases.push_back({stem + name, scene_path, v});
      }
    }
  } else if (cases_text != "all") {
    std::erase_if(cases, [&](const Case& c) { return cases_text.find(c.name) == std::string::npos; });
    if (cases.empty()) {
      std::cerr << "--cases " << cases_text << ": none of background-blur, foreground-blur, partial-occlusion\n";
      return 2;
    }
  }
  if (!png_dir.empty()) std::filesystem::create_directories(png_dir);
  std::ofstream csv;
  if (!csv_path.empty()) {
    csv.open(csv_path);
    if (!csv) {
      std::cerr << "cannot write " << csv_path << "\n";
      return 1;
    }
    csv << "scene,mean_coc_px,method,psnr_db,ssim,leak_rmse,edge_rmse,ms_per_frame,reference_samples,"
           "reference_seconds,gpu_ms,vs_cpu_db,device,reference_aperture_sigma,vs_gather_db,interior_psnr_db,"
           "interior_fraction\n";
  }
  // The OpenGL implementations' context (EGL): their rows are skipped, with the reason, without one.
  std::unique_ptr<GlBackend> gl_context;
  std::unique_ptr<GlLeeMipmap> gl_mipmap;
  std::unique_ptr<GlSchedlLayered> gl_schedl;
  std::unique_ptr<GlLeeSplat> gl_splat;
  std::string gl_device;
  if (method_selected("lee-mipmap gl") || method_selected("schedl-layered gl") || method_selected("lee-splat gl")) {
    try {
      gl_context = std::make_unique<GlBackend>();
      gl_context->context().make_current();
      const bool compute = gl_context->context().features().at_least(4, 3);
      gl_mipmap = std::make_unique<GlLeeMipmap>(compute);
      gl_schedl = std::make_unique<GlSchedlLayered>(compute);
      gl_splat = std::make_unique<GlLeeSplat>(compute);
      gl_device = "OpenGL " + gl_context->context().features().version() + " (" + gl_context->context().renderer() + ")";
      std::printf("gl rows on %s\n", gl_device.c_str());
    } catch (const std::exception& e) {
      std::printf("gl rows skipped: %s\n", e.what());
    }
  }
  std::printf("reference: %s\n", aperture_sigma > 0 ? ("Gaussian aperture, sigma = " + std::to_string(aperture_sigma) +
                                                         " x CoC").c_str()
                                                    : "uniform disc aperture (the thin lens)");
  std::printf("%-18s %6s %-27s %8s %7s %9s %9s %9s %10s %8s %9s %9s\n", "scene", "coc", "method", "psnr_db", "ssim",
              "leak_rmse", "edge_rmse", "interior", "ms/frame", "gpu_ms", "vs_cpu_db", "vs_gather");

  for (Case& cs : cases) {
    // A user's file may be missing or malformed: the loader's message, not a crash.
    Scene scene;
    try {
      scene = load_scene(cs.file);
    } catch (const SceneError& e) {
      std::cerr << "cannot load the scene: " << e.what() << "\n";
      return 2;
    }
    scene.camera.width = w;
    scene.camera.height = h;
    EmbreeBackend backend;
    backend.set_scene(scene);
    GBuffer g, hidden;
    backend.render({}, {}, g);
    BackendSettings peel;
    peel.peel = 1;
    backend.render({}, peel, hidden);
    if (cs.focus_percentile >= 0) {
      cs.focus_m = hit_depth_percentile(g, cs.focus_percentile);
      if (!std::isfinite(cs.focus_m)) {
        std::cerr << cs.file << ": no pixel of the pinhole image hits geometry: no depth to focus on\n";
        return 2;
      }
      std::printf("%s: focus %.2f m (%.0fth percentile of the pinhole depth)\n", cs.name.c_str(), cs.focus_m,
                  100.0 * cs.focus_percentile);
    }
    const Lens base_lens = scene.camera.lens;
    for (const double target : cocs) {
      // Mean CoC is linear in the aperture: scale E so the mean over the image is the target.
      Scene s = scene;
      s.camera.lens.aperture_m = base_lens.aperture_m > 0 ? base_lens.aperture_m : base_lens.focal_length_m / 2.8;
      CocModel coc = coc_model(s.camera, s.display, cs.focus_m, CocProjection::Sensor);
      const double mean0 = failure_masks(g, coc).mean_coc;
      s.camera.lens.aperture_m *= target / std::max(1e-9, mean0);
      coc = coc_model(s.camera, s.display, cs.focus_m, CocProjection::Sensor);
      const Masks masks = failure_masks(g, coc);
      std::printf("%-18s %6.1f interior (no depth discontinuity within reach): %.1f %% of the pixels\n",
                  cs.name.c_str(), target, 100.0 * cv::countNonZero(masks.interior) / (static_cast<double>(w) * h));

      DofReference ref(backend, {}, {}, s.camera.lens, cs.focus_m, ReferenceKind::RayTraced, 1, aperture_sigma);
      if (convergence > 0 && &cs == &cases.front() && target == cocs.back()) {
        DofReference truth(backend, {}, {}, s.camera.lens, cs.focus_m, ReferenceKind::RayTraced, 77, aperture_sigma);
        truth.add_samples(convergence);
        const cv::Mat t = as_mat(to_ldr(truth.image(), w, h));
        DofReference probe(backend, {}, {}, s.camera.lens, cs.focus_m, ReferenceKind::RayTraced, 1, aperture_sigma);
        for (std::uint32_t n = 4; n <= convergence / 4; n *= 2) {
          probe.add_samples(n - probe.samples());
          const cv::Mat p = as_mat(to_ldr(probe.image(), w, h));
          std::printf("convergence %-18s coc %5.1f: %5u samples psnr %6.2f dB against %u (%.1f s)\n", cs.name.c_str(),
                      target, n, psnr(p, t), convergence, probe.seconds());
          if (csv) {
            csv << cs.name << "," << target << ",reference-" << n << "-samples," << psnr(p, t) << "," << ssim(p, t)
                << ",,,," << n << "," << probe.seconds() << "\n";
          }
        }
      }
      ref.add_samples(samples);
      const RgbImage ref_hdr = ref.image();
      const cv::Mat ref_ldr = as_mat(to_ldr(ref_hdr, w, h));
      if (!png_dir.empty()) {
        cv::Mat bgr;
        cv::cvtColor(ref_ldr, bgr, cv::COLOR_RGB2BGR);
        char name[256];
        std::snprintf(name, sizeof name, "%s/%s-coc%02d-reference.png", png_dir.c_str(), cs.name.c_str(),
                      static_cast<int>(target));
        cv::imwrite(name, bgr);
      }

      DofInput in;
      in.width = w;
      in.height = h;
      in.color = g.color.data();
      in.depth = g.depth.data();
      in.coc = coc;
      struct Method {
        std::string name;
        std::function<void(RgbImage&)> run;
        // The OpenGL rows: their GPU time of the last run, and the CPU implementation they mirror.
        double* gpu_ms = nullptr;
        std::function<void(RgbImage&)> cpu_twin = nullptr;
        // The CPU lee-mipmap rows: the sigma per CoC of the gaussian gather that is their exact twin.
        double gather_twin = 0;
      };
      // The gaussian gather rows' images by sigma per CoC, for the lee-mipmap rows after them.
      std::map<double, cv::Mat> gathered;
      double gl_ms = 0;
      LeeMipmap mip;
      std::vector<Method> methods;
      methods.push_back({"pinhole (no dof)", [&](RgbImage& out) { out.assign(g.color.begin(), g.color.end()); }});
      for (const double dob : {0.5, 0.25}) {
        methods.push_back({dob == 0.5 ? "gaussian gather sigma=C/2" : "gaussian gather sigma=C/4",
                           [&, dob](RgbImage& out) { gaussian_gather(in, {.sigma_per_coc = dob}, out); }});
      }
      methods.push_back({"lee-mipmap", [&](RgbImage& out) { mip.run(in, LeeMipmapSettings{}, out); }, nullptr,
                         nullptr, 0.5});
      methods.push_back({"lee-mipmap isotropic", [&](RgbImage& out) {
                           LeeMipmapSettings ls;
                           ls.anisotropic = false;
                           mip.run(in, ls, out);
                         },
                         nullptr, nullptr, 0.5});
      // Isotropic and without smoothing: the mipmap's blur (eqs. 4.5-4.8) alone, the gather's approximation.
      for (const double dob : {0.5, 0.25}) {
        LeeMipmapSettings ls;
        ls.anisotropic = false;
        ls.smooth_foreground = false;
        ls.dob_per_coc = dob;
        methods.push_back({dob == 0.5 ? "lee-mipmap plain" : "lee-mipmap plain sigma=C/4",
                           [&, ls](RgbImage& out) { mip.run(in, ls, out); }, nullptr, nullptr, dob});
      }
      methods.push_back({"lee-mipmap no-smoothing", [&](RgbImage& out) {
                           LeeMipmapSettings ls;
                           ls.smooth_foreground = false;
                           mip.run(in, ls, out);
                         },
                         nullptr, nullptr, 0.5});
      methods.push_back({"lee-mipmap linear blend", [&](RgbImage& out) {
                           LeeMipmapSettings ls;
                           ls.geometric = false;
                           mip.run(in, ls, out);
                         },
                         nullptr, nullptr, 0.5});
      methods.push_back({"lee-mipmap sigma=C/4", [&](RgbImage& out) {
                           LeeMipmapSettings ls;
                           ls.dob_per_coc = 0.25;
                           mip.run(in, ls, out);
                         },
                         nullptr, nullptr, 0.25});
      if (gl_mipmap) {
        for (const GlLeeMipmap::Pass pass : {GlLeeMipmap::Pass::Fragment, GlLeeMipmap::Pass::Compute}) {
          if (pass == GlLeeMipmap::Pass::Compute && !gl_mipmap->has_compute()) continue;
          const std::string name = pass == GlLeeMipmap::Pass::Compute ? "lee-mipmap gl compute" : "lee-mipmap gl";
          for (const double dob : {0.5, 0.25}) {
            LeeMipmapSettings ls;
            ls.dob_per_coc = dob;
            methods.push_back({dob == 0.5 ? name : name + " sigma=C/4",
                               [&, ls, pass](RgbImage& out) { gl_mipmap->run_image(in, ls, out, &gl_ms, pass); }, &gl_ms,
                               [&, ls](RgbImage& out) { mip.run(in, ls, out); }});
          }
        }
      }
      methods.push_back({"lee-splat no hidden", [&](RgbImage& out) {
                           LeeSplatSettings ls;
                           ls.use_hidden = false;
                           lee_splat(in, ls, out);
                         }});
      // With the hidden image: its render (a second, peeled G-buffer) is part of the method's time.
      methods.push_back({"lee-splat", [&](RgbImage& out) {
                           backend.render({}, peel, hidden);
                           DofInput with = in;
                           with.hidden_color = hidden.color.data();
                           with.hidden_depth = hidden.depth.data();
                           lee_splat(with, LeeSplatSettings{}, out);
                         }});
      // The GL passes with the same hidden image (rendered once here, uploaded each run): gpu_ms is the
      // passes alone, without the peeling (on the GPU path: gpu.peel).
      GBuffer gl_hidden;
      if (gl_splat) {
        backend.render({}, peel, gl_hidden);
        for (const GlLeeSplat::Pass pass : {GlLeeSplat::Pass::Fragment, GlLeeSplat::Pass::Compute}) {
          if (pass == GlLeeSplat::Pass::Compute && !gl_splat->has_compute()) continue;
          methods.push_back({pass == GlLeeSplat::Pass::Compute ? "lee-splat gl compute" : "lee-splat gl",
                             [&, pass](RgbImage& out) {
                               DofInput with = in;
                               with.hidden_color = gl_hidden.color.data();
                               with.hidden_depth = gl_hidden.depth.data();
                               gl_splat->run_image(with, LeeSplatSettings{}, out, &gl_ms, pass);
                             },
                             &gl_ms, [&](RgbImage& out) {
                               DofInput with = in;
                               with.hidden_color = gl_hidden.color.data();
                               with.hidden_depth = gl_hidden.depth.data();
                               lee_splat(with, LeeSplatSettings{}, out);
                             }});
        }
      }
      // Schedl & Wimmer on M = 3 depth-peeled layers (the two peel renders are part of its time) and on
      // the visible layer alone (M = 1).
      GBuffer peel1, peel2;
      methods.push_back({"schedl-layered M=3", [&](RgbImage& out) {
                           BackendSettings p1, p2;
                           p1.peel = 1;
                           p2.peel = 2;
                           backend.render({}, p1, peel1);
                           backend.render({}, p2, peel2);
                           schedl_layered(in, {{peel1.color.data(), peel1.depth.data()}, {peel2.color.data(), peel2.depth.data()}},
                                          SchedlSettings{}, out);
                         }});
      methods.push_back({"schedl-layered M=1", [&](RgbImage& out) { schedl_layered(in, {}, SchedlSettings{}, out); }});
      // The GL passes on the ray tracer's peeled layers (rendered once here, uploaded each run): gpu_ms
      // is the passes alone, without the peeling (on the GPU path: gpu.peel, bench_gpu_frame.sh).
      if (gl_schedl) {
        BackendSettings p1, p2;
        p1.peel = 1;
        p2.peel = 2;
        backend.render({}, p1, peel1);
        backend.render({}, p2, peel2);
        for (const GlSchedlLayered::Pass pass : {GlSchedlLayered::Pass::Fragment, GlSchedlLayered::Pass::Compute}) {
          if (pass == GlSchedlLayered::Pass::Compute && !gl_schedl->has_compute()) continue;
          methods.push_back({pass == GlSchedlLayered::Pass::Compute ? "schedl-layered gl compute M=3" : "schedl-layered gl M=3",
                             [&, pass](RgbImage& out) {
                               gl_schedl->run_image(in, {{peel1.color.data(), peel1.depth.data()},
                                                         {peel2.color.data(), peel2.depth.data()}},
                                                    SchedlSettings{}, out, &gl_ms, pass);
                             },
                             &gl_ms, [&](RgbImage& out) {
                               schedl_layered(in, {{peel1.color.data(), peel1.depth.data()},
                                                   {peel2.color.data(), peel2.depth.data()}},
                                              SchedlSettings{}, out);
                             }});
        }
      }
      methods.push_back({"accum (embree 16 views)", [&](RgbImage& out) {
                           DofReference a(backend, {}, {}, s.camera.lens, cs.focus_m, ReferenceKind::Accumulation, 1);
                           a.add_samples(16);
                           out = a.image();
                         }});
      for (const std::string& f : method_filter) {
        if (std::none_of(methods.begin(), methods.end(), [&](const Method& m) { return m.name.rfind(f, 0) == 0; })) {
          std::cerr << "--methods: '" << f << "' names no method; methods are:";
          for (const Method& m : methods) std::cerr << " '" << m.name << "'";
          std::cerr << "\n";
          return 2;
        }
      }
      for (const Method& m : methods) {
        if (!method_selected(m.name)) continue;
        RgbImage out;
        std::vector<double> ms;
        // The accumulation baseline is 16 full renders: once is enough to time it.
        const std::uint32_t runs = m.name.rfind("accum", 0) == 0 ? 1 : repeats;
        for (std::uint32_t r = 0; r < runs; ++r) {
          const auto start = Clock::now();
          m.run(out);
          ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
        }
        const cv::Mat ldr = as_mat(to_ldr(out, w, h));
        const double p = psnr(ldr, ref_ldr), q = ssim(ldr, ref_ldr);
        const double leak = masked_rmse(ldr, ref_ldr, masks.leak), edge = masked_rmse(ldr, ref_ldr, masks.edge);
        const double interior = 20.0 * std::log10(255.0 / masked_rmse(ldr, ref_ldr, masks.interior));
        // The OpenGL rows: the GPU time (median over the runs) and the agreement with the CPU twin.
        std::vector<double> gpu;
        double vs_cpu = std::nan("");
        if (m.gpu_ms != nullptr) {
          for (std::uint32_t r = 0; r < runs; ++r) {
            RgbImage again;
            m.run(again);
            gpu.push_back(*m.gpu_ms);
          }
          RgbImage twin;
          m.cpu_twin(twin);
          vs_cpu = psnr(ldr, as_mat(to_ldr(twin, w, h)));
        }
        if (m.name.rfind("gaussian gather sigma=C/", 0) == 0) gathered[m.name.back() == '2' ? 0.5 : 0.25] = ldr;
        const auto gather = gathered.find(m.gather_twin);
        const double vs_gather = gather != gathered.end() ? psnr(ldr, gather->second) : std::nan("");
        std::printf("%-18s %6.1f %-27s %8.2f %7.4f %9.2f %9.2f %9.2f %10.2f %8.2f %9.2f %9.2f\n", cs.name.c_str(),
                    target, m.name.c_str(), p, q, leak, edge, interior, median(ms), median(gpu), vs_cpu, vs_gather);
        std::fflush(stdout);
        if (csv) {
          csv << cs.name << "," << target << "," << m.name << "," << p << "," << q << "," << leak << "," << edge << ","
              << median(ms) << "," << samples << "," << ref.seconds() << ",";
          if (m.gpu_ms != nullptr) {
            csv << median(gpu) << "," << vs_cpu << ",\"" << gl_device << "\"";
          } else {
            csv << ",,cpu";
          }
          csv << "," << aperture_sigma << ",";
          if (std::isfinite(vs_gather)) csv << vs_gather;
          csv << "," << interior << ","
              << cv::countNonZero(masks.interior) / (static_cast<double>(w) * static_cast<double>(h)) << "\n";
        }
        if (!png_dir.empty()) {
          cv::Mat bgr;
          cv::cvtColor(ldr, bgr, cv::COLOR_RGB2BGR);
          std::string tag = m.name;
          std::replace(tag.begin(), tag.end(), ' ', '_');
          std::replace(tag.begin(), tag.end(), '/', '_');  // "sigma=C/4" is not a directory
          std::erase_if(tag, [](char ch) { return ch == '(' || ch == ')' || ch == ','; });
          char name[300];
          std::snprintf(name, sizeof name, "%s/%s-coc%02d-%s.png", png_dir.c_str(), cs.name.c_str(),
                        static_cast<int>(target), tag.c_str());
          cv::imwrite(name, bgr);
        }
      }
    }
  }
  return 0;
}
