// SPDX-License-Identifier: Apache-2.0
#pragma once
// The contrast sensitivity of the human eye across the visual field (Geisler & Perry 1998, as
// numbered in Murphy 2007 §4.4.3): which spatial frequencies a viewer can see at which eccentricity.
// Gaze-contingent methods ask it how much detail a region needs: the CSF-driven ray casting of the
// gi pass (gi/csf_mask.h) and the gaze policy of the LOD pass (lod/lod_policy.h).
//
//   CT(f, e)  = CT0 exp(alpha f (e + e2) / e2)                     Murphy 2007, eq. 4.1
//   e_c(f)    = e2 / (alpha f) ln(1 / CT0) - e2    (CT = 1)         Murphy 2007, eq. 4.2
//   f_c(e)    = e2 ln(1 / CT0) / (alpha (e + e2))  (CT = 1)         Murphy 2007, eq. 4.3
// f in cycles/deg, e in degrees from the point of regard. The paper names the constants but gives no
// values ("Geisler and Perry have determined empirical values"), so the defaults are Geisler &
// Perry's fit: alpha = 0.106, e2 = 2.3 deg, CT0 = 1/64 (f_c(0) = ln 64 / 0.106 = 39.2 cycles/deg).
#include <string>

namespace fovea::render::perception {

struct GeislerPerry {
  double ct0 = 1.0 / 64.0;  // minimum contrast threshold CT0, (0, 1)
  double alpha = 0.106;     // spatial frequency decay constant
  double e2_deg = 2.3;      // half-resolution eccentricity, degrees
};

// Empty when the constants are usable; otherwise "PREFIXfield = value (allowed range)".
std::string validate(const GeislerPerry& model, const char* prefix = "GeislerPerry.");

// Murphy 2007, eq. 4.1: the contrast threshold at spatial frequency f (cycles/deg) and eccentricity
// e (deg). Negative e is taken as |e|.
double contrast_threshold(double frequency_cpd, double eccentricity_deg, const GeislerPerry& model);
// Murphy 2007, eq. 4.2: the eccentricity beyond which frequency f is invisible (CT = 1). Negative
// when f is above the foveal cutoff f_c(0); +infinity for f <= 0.
double cutoff_eccentricity_deg(double frequency_cpd, const GeislerPerry& model);
// Murphy 2007, eq. 4.3: the highest visible frequency (CT = 1) at eccentricity e; f_c(0) =
// ln(1/CT0) / alpha.
double cutoff_frequency_cpd(double eccentricity_deg, const GeislerPerry& model);

}  // namespace fovea::render::perception
