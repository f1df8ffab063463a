// SPDX-License-Identifier: Apache-2.0
#include "classify/context.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace fovea::trackerd::classify {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

std::string ms(double s) { return std::to_string(static_cast<int>(std::lround(s * 1000))) + "ms"; }

// The first sample at or after time t (buf.size() if none), by bisection: context_features without
// a cursor (ContextCursor walks to the same index).
std::size_t first_at_or_after(const std::deque<ContextSample>& buf, double t) {
  return static_cast<std::size_t>(
      std::partition_point(buf.begin(), buf.end(), [t](const ContextSample& s) { return s.t < t; }) - buf.begin());
}

// The sample d from sample i (d < 0: before): the furthest from i that is at most |d| away and over
// |d|/2 away (each by more than kContextSlackS), so never beyond the look-ahead whatever the rate; none
// (buf.size()) where there is no such sample (a pause in the stream, or a rate too low for d).
// find(t): the first sample at or after t.
template <class Find>
std::size_t at_offset(const std::deque<ContextSample>& buf, std::size_t i, double d, Find find) {
  const double t = buf[i].t;
  std::size_t k = buf.size();
  if (d > 0) {
    const std::size_t j = find(t + d + kContextSlackS);  // the first beyond
    if (j > i + 1) k = j - 1;
  } else {
    const std::size_t j = find(t + d - kContextSlackS);  // the first at or after t + d
    if (j < i) k = j;
  }
  return k < buf.size() && std::abs(buf[k].t - t) > std::abs(d) / 2 + kContextSlackS ? k : buf.size();
}

// The running totals just after sample k (before it plus its own).
struct Totals {
  std::array<double, kMaxTreeClasses> sum{};
  double gaze = 0, all = 0;
};
Totals before(const ContextSample& s) { return {s.before, s.gaze_before, s.all_before}; }
Totals after(const ContextSample& s, std::size_t classes) {
  Totals r = before(s);
  if (s.gaze) {
    for (std::size_t c = 0; c < classes; ++c) r.sum[c] += s.p[c];
    r.gaze += 1;
  }
  r.all += 1;
  return r;
}

// Means over the samples strictly between totals a (taken after the first) and b (taken before the
// last): classes means then the gaze share, NaN where there is no sample (or no gaze).
void window(const Totals& a, const Totals& b, std::size_t classes, float* out) {
  const double gaze = b.gaze - a.gaze, all = b.all - a.all;
  for (std::size_t c = 0; c < classes; ++c) out[c] = gaze > 0 ? static_cast<float>((b.sum[c] - a.sum[c]) / gaze) : kNaNf;
  out[classes] = all > 0 ? static_cast<float>(gaze / all) : kNaNf;
}

void probabilities_of(const std::deque<ContextSample>& buf, std::size_t j, std::size_t classes, float* out) {
  for (std::size_t c = 0; c < classes; ++c) {
    out[c] = j < buf.size() && buf[j].gaze ? static_cast<float>(buf[j].p[c]) : kNaNf;
  }
}

}  // namespace

std::size_t ContextCursor::first_at_or_after(const std::deque<ContextSample>& buf, std::size_t slot, double t) {
  std::size_t k = std::min(at_[slot], buf.size());
  while (k < buf.size() && buf[k].t < t) ++k;
  at_[slot] = k;
  return k;
}

void push_context(std::deque<ContextSample>& buf, ContextSample s, std::size_t classes) {
  if (!buf.empty()) {
    const Totals t = after(buf.back(), classes);
    s.before = t.sum, s.gaze_before = t.gaze, s.all_before = t.all;
  }
  buf.push_back(s);
}

std::vector<std::string> context_feature_names(const std::vector<std::string>& classes) {
  std::vector<std::string> n;
  for (const std::string& c : classes) n.push_back("p_" + c);
  for (const char* side : {"_m", "_p"}) {
    for (double d : kContextOffsetsS) {
      for (const std::string& c : classes) n.push_back("p_" + c + side + ms(d));
    }
  }
  for (const char* side : {"_m", "_p"}) {
    for (double w : kContextWindowsS) {
      for (const std::string& c : classes) n.push_back("mean_" + c + side + ms(w));
      n.push_back(std::string("gaze") + side + ms(w));
    }
  }
  for (const std::string& f : feature_names()) n.push_back(f);
  return n;
}

double context_feature_reach_s(const std::string& name) {
  // "..._p<N>ms": N ms ahead; every other name looks at the sample or back.
  const std::size_t at = name.rfind("_p");
  if (at == std::string::npos || name.size() < at + 5 || name.compare(name.size() - 2, 2, "ms") != 0) return 0;
  const std::string digits = name.substr(at + 2, name.size() - at - 4);
  if (digits.empty() || !std::all_of(digits.begin(), digits.end(), [](char ch) { return ch >= '0' && ch <= '9'; })) {
    return 0;
  }
  return std::stod(digits) / 1000.0;
}

void context_features(const std::deque<ContextSample>& buf, std::size_t i, std::size_t classes, double lookahead_s,
                      float* out, ContextCursor* cursor) {
  const ContextSample& s = buf[i];
  std::size_t slot = 0;  // each search its own cursor slot, in the same order at every sample
  const auto find = [&](double t) {
    return cursor ? cursor->first_at_or_after(buf, slot++, t) : first_at_or_after(buf, t);
  };
  // Beyond the look-ahead a feature is NaN even where the buffer happens to reach (offline and
  // online then agree for every look-ahead).
  const auto visible = [lookahead_s](double reach) { return reach <= lookahead_s + 1e-9; };
  float* o = out;
  probabilities_of(buf, i, classes, o);
  o += classes;
  for (double sign : {-1.0, 1.0}) {
    for (double d : kContextOffsetsS) {
      if (sign > 0 && !visible(d)) {
        std::fill(o, o + classes, kNaNf);
      } else {
        probabilities_of(buf, at_offset(buf, i, sign * d, find), classes, o);
      }
      o += classes;
    }
  }
  for (double sign : {-1.0, 1.0}) {
    for (double w : kContextWindowsS) {
      if (sign > 0 && !visible(w)) {
        std::fill(o, o + classes + 1, kNaNf);
      } else if (sign < 0) {  // [t - w, t): from the first sample at or after t - w up to this one
        window(before(buf[find(s.t - w - kContextSlackS)]), before(s), classes, o);
      } else {  // (t, t + w]: from the one after this up to the last at or before t + w
        const std::size_t last = find(s.t + w + kContextSlackS);
        window(after(s, classes), last < buf.size() ? before(buf[last]) : after(buf.back(), classes), classes, o);
      }
      o += classes + 1;
    }
  }
  std::copy(s.frame.begin(), s.frame.end(), o);
}

}  // namespace fovea::trackerd::classify
