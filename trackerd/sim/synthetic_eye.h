// SPDX-License-Identifier: Apache-2.0
#pragma once
// Synthetic infrared eye images with exact ground truth, for tests, benchmarks and the daemon's
// synthetic-eye source. An eye model (rotation centre, spherical cornea, pupil disc, iris) is seen by
// a pinhole camera with infrared LEDs around its lens, so the pupil and the corneal glints move with
// gaze as they do in real video trackers, and the pupil–glint vector maps to gaze as theirs does.
//
// Geometry (head frame, millimetres): origin at the eye's rotation centre; x right, y down, z
// forward (towards the screen). At yaw = pitch = 0 the optical axis is +z. Positive yaw turns the
// eye right (+x), positive pitch turns it down (+y) — the same signs as screen degrees:
//   d(yaw, pitch) = (sin yaw cos pitch, sin pitch, cos yaw cos pitch).
// The cornea is a sphere about C = rotation_to_cornea * d; the pupil and the iris are discs about
// P = C + cornea_to_pupil * d in the plane normal to d. Corneal refraction is ignored: the pupil
// is imaged where it physically is, so EyeTruth::pupil is the exact image conic of that disc.
// The camera's image x is its "right", image y its "down", chosen so image down is as close to
// head +y as possible; a camera facing the eye therefore sees the eye mirrored (positive yaw
// moves the pupil towards image left with the default camera), as a real eye camera does.
#include <cstdint>
#include <memory>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "eye/ellipse.h"
#include "eye/led_layout.h"

namespace fovea::trackerd::eye {

struct EyeModel {
  // Typical adult values (Le Grand / Gullstrand schematic eye; Guestrin & Eizenman 2006).
  double cornea_radius_mm = 7.8;          // radius of corneal curvature
  double rotation_to_cornea_mm = 5.7;     // rotation centre -> centre of corneal curvature
  double cornea_to_pupil_mm = 4.2;        // centre of corneal curvature -> pupil centre (K)
  double pupil_radius_mm = 2.0;           // 1.0 (bright light) .. 4.0 (dark)
  double iris_radius_mm = 6.0;
  double eyeball_radius_mm = 12.0;
};

struct EyeCamera {
  // Camera position in the head frame and the point it looks at (aimed so the eye is centred).
  cv::Point3d position_mm{0.0, 18.0, 38.0};  // below the eye and in front: a head-mounted eye camera
  cv::Point3d look_at_mm{0.0, 0.0, 8.0};
  double horizontal_fov_deg = 50.0;          // sets the focal length for the image width
};

struct SyntheticEyeOptions {
  int width = 320, height = 240;
  std::uint64_t seed = 1;
  EyeModel eye;
  EyeCamera camera;
  LedLayout leds = LedLayout::preset(2);  // 0..5 LEDs; each makes one glint when visible

  // Image effects. Grey levels are 0..255.
  double noise_sigma = 2.0;          // Gaussian sensor noise, grey levels
  double motion_blur_px = 0.0;       // length of a linear motion-blur kernel
  double motion_blur_angle_deg = 0.0;
  double defocus_px = 0.0;           // radius of a disc (defocus) blur
  double eyelid_cover = 0.0;         // fraction of the pupil's vertical extent covered by the upper lid, 0..1
  bool eyelashes = true;
  double eyelash_length = 1.0;       // every lash times this, 0.2..4: at 2.5 the long ones hang across the pupil
  // Lashes lit by the infrared LEDs: drawn at their own level over everything, so across the pupil
  // (darker than a lash) they show as grey lines, as real infrared cameras see them; off, they only
  // darken what they cover and vanish over the pupil.
  bool lit_lashes = false;
  bool glasses_reflection = false;   // large soft reflections from spectacle lenses
  double illumination_gradient = 0.0;  // 0..1: strength of uneven illumination (a tilted gradient + vignette)
  // Weak infrared light: every level the LEDs light (the eye, skin, glints, spectacle reflections)
  // times this, 0.05..2, while the sensor's noise stays: 0.3 leaves a third of the signal.
  double exposure = 1.0;
  // A dark iris: 0 keeps the instance's iris (about 80 grey levels above its pupil next to it); 2..150
  // sets how many grey levels the iris next to the pupil stands above the pupil, its texture scaled
  // with it. Dark-brown irises under infrared: 5..15 (issue 44; real desk-mounted sets: about 9).
  double pupil_iris_contrast = 0.0;
  // Puts one glint exactly on the pupil boundary in every frame: the pupil radius is set (within
  // 1..4 mm) so that the boundary passes through the glint nearest to it; when no radius in that
  // range does, that LED is displaced for the frame (EyeTruth::leds_used says where).
  bool glint_on_pupil_edge = false;

  // Checks every field; throws std::invalid_argument naming the field and its allowed range.
  void validate() const;
};

// What is in a rendered frame, exactly.
struct EyeTruth {
  double yaw_deg = 0, pitch_deg = 0;  // optical-axis direction rendered
  double openness = 1;                // 1 open, 0 closed
  bool closed = false;                // lids closed: no pupil visible at all (pupil_visible_fraction == 0)
  Ellipse pupil;                      // the projected pupil boundary (exact conic), valid unless closed
  double pupil_visible_fraction = 1;  // share of the pupil disc's image area not hidden by lids
  std::vector<cv::Point2d> glints;    // visible glint centres, pixels
  std::vector<int> glint_led;         // the LED index of each visible glint
  cv::Point2d glint_centroid;         // centroid of all LEDs' glints (visible or not); with no LEDs,
                                      // where the glint of an LED at the lens centre would be
  cv::Point2d pupil_glint;            // pupil.centre - glint_centroid (pixels)
  double pupil_radius_mm = 0;         // as rendered (differs from the model with glint_on_pupil_edge)
  LedLayout leds_used;                // as rendered
};

class SyntheticEye {
 public:
  explicit SyntheticEye(SyntheticEyeOptions options);  // validates: throws std::invalid_argument
  const SyntheticEyeOptions& options() const { return options_; }
  const LedLayout& leds() const { return options_.leds; }

  // Ground truth only (no image): used to fit model-based maps and by tests.
  EyeTruth project(double yaw_deg, double pitch_deg, double openness = 1.0) const;
  // Renders one 8-bit GREY frame of options().width x height. Deterministic for a given seed and
  // call sequence: the eye's appearance (iris texture, skin, lashes, spectacle reflections, the
  // direction of uneven illumination) is fixed per instance by the seed, as a person and a headset
  // are; each frame draws only its sensor noise from the instance's generator. truth may be null.
  cv::Mat render(double yaw_deg, double pitch_deg, double openness, EyeTruth* truth);
  // project() and render() throw std::invalid_argument for a non-finite angle or openness; angles
  // are clamped to [-60, 60] degrees and openness to [0, 1] (EyeTruth reports what was rendered).

 private:
  struct Look;   // the instance's fixed appearance (iris texture, skin, lashes, reflections), from the seed
                 // (synthetic_eye_look.h)
  struct Frame;  // one frame's geometry (synthetic_eye_geometry.h)
  Frame frame(double yaw_deg, double pitch_deg, double openness) const;
  struct RenderStages;  // render()'s stages that read Look (synthetic_eye_render.cpp)

  SyntheticEyeOptions options_;
  std::mt19937_64 rng_;
  std::shared_ptr<const Look> look_;  // immutable, so copies may share it
};

}  // namespace fovea::trackerd::eye
