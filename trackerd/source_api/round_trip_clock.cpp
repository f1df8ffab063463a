// SPDX-License-Identifier: Apache-2.0
#include "source_api/round_trip_clock.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace fovea::trackerd {

namespace {
constexpr std::int64_t kBucketNs = 10'000'000'000;   // one kept exchange per 10 s
constexpr std::int64_t kHistoryNs = 120'000'000'000; // the fit looks back 2 minutes
// The least-squares slope is trusted once every slope the used exchanges allow lies within this
// much of every other (20 ppm: at most 0.2 ms off ten seconds past the last bucket).
constexpr double kPinnedSlope = 20e-6;
constexpr std::int64_t kJumpNs = 100'000'000;        // a remote clock off by more has restarted
constexpr double kMaxRemoteS = 1e12;                 // ~31,700 years: beyond it a remote time is junk
}  // namespace

std::int64_t RoundTripClock::Exchange::offset_ns() const {
  return host_mid_ns - static_cast<std::int64_t>(std::llround(remote_s * 1e9));
}

void RoundTripClock::add(std::int64_t host_send_ns, std::int64_t host_receive_ns, double remote_s) {
  if (!(host_receive_ns >= host_send_ns) || !std::isfinite(remote_s) || std::abs(remote_s) > kMaxRemoteS) return;
  const std::int64_t rtt = host_receive_ns - host_send_ns;
  const Exchange e{host_send_ns + rtt / 2, rtt, remote_s};
  last_rtt_ns_ = rtt;
  ++count_;
  if (ready() && std::llabs(to_host_ns(remote_s) - e.host_mid_ns) > kJumpNs + rtt) {
    exchanges_.clear();
    have_line_ = false;
    ++resets_;
  }
  if (!exchanges_.empty() && e.host_mid_ns / kBucketNs == exchanges_.back().host_mid_ns / kBucketNs) {
    if (rtt < exchanges_.back().rtt_ns) exchanges_.back() = e;  // the bucket keeps its fastest
  } else {
    exchanges_.push_back(e);
  }
  while (exchanges_.size() > 1 && exchanges_.front().host_mid_ns < e.host_mid_ns - kHistoryNs) exchanges_.pop_front();
  fit();
}

namespace {

// The slopes b for which some line offset = a + b t passes within every used exchange's +-rtt/2:
// b (t_j - t_i) <= (o_j + u_j) - (o_i - u_i) for every pair t_i < t_j, and the mirror bound.
// lo > hi when no line fits them all (the remote clock's rate changed within the window).
template <class Exchanges>
RoundTripClock::SlopeRange allowed_slopes(const Exchanges& used) {
  RoundTripClock::SlopeRange r;
  for (std::size_t i = 0; i < used.size(); ++i) {
    for (std::size_t j = i + 1; j < used.size(); ++j) {
      const double dt = static_cast<double>(used[j]->host_mid_ns - used[i]->host_mid_ns);
      if (dt <= 0) continue;
      const double d_offset = static_cast<double>(used[j]->offset_ns() - used[i]->offset_ns());
      const double slack = static_cast<double>(used[i]->rtt_ns + used[j]->rtt_ns) / 2;
      r.hi = std::min(r.hi, (d_offset + slack) / dt);
      r.lo = std::max(r.lo, (d_offset - slack) / dt);
    }
  }
  return r;
}

}  // namespace

// The slopes every kept exchange allows (a slow one allows many, so all of them count) decide:
//  - while they span more than kPinnedSlope (buckets are cut at fixed host times, so two can be
//    milliseconds apart, and a slope through them is mostly their errors), or fewer than two
//    buckets' fastest exchanges are nearly as fast as the fastest of all: the allowed slope nearest
//    zero, through the fastest exchange. It is off by at most the true drift, so the mapping is never
//    worse than ignoring the drift, and it follows as much drift as the exchanges already show;
//  - else least squares through those nearly as fast (a bucket that saw only slow, lopsided
//    exchanges would tilt it), its slope kept within the allowed ones; drift_ppm() reports it.
// Exchanges no line passes through (the remote's rate changed within the window): least squares
// unbounded, or the fastest alone.
void RoundTripClock::fit() {
  const auto best = std::min_element(exchanges_.begin(), exchanges_.end(),
                                     [](const Exchange& p, const Exchange& q) { return p.rtt_ns < q.rtt_ns; });
  const std::int64_t good_rtt = 2 * best->rtt_ns + 50'000;
  std::vector<const Exchange*> used;
  for (const Exchange& x : exchanges_) {
    if (x.rtt_ns <= good_rtt) used.push_back(&x);
  }
  origin_ns_ = best->host_mid_ns;
  const std::int64_t base = best->offset_ns();
  a_ns_ = static_cast<double>(base);
  b_ = 0;
  have_line_ = false;
  std::vector<const Exchange*> all;
  for (const Exchange& x : exchanges_) all.push_back(&x);
  const SlopeRange allowed = allowed_slopes(all);
  const bool consistent = allowed.lo <= allowed.hi;
  if (consistent && (used.size() < 2 || allowed.hi - allowed.lo > kPinnedSlope)) {
    b_ = std::clamp(0.0, allowed.lo, allowed.hi);
    return;
  }
  if (used.size() < 2) return;
  fit_least_squares(used, base, consistent ? allowed : SlopeRange{});
  have_line_ = true;
}

// offset(host_mid) = a + b (host_mid - origin) through `used` (relative to `base` for precision), the
// slope kept within `allowed` and the line through the exchanges' mean point.
void RoundTripClock::fit_least_squares(const std::vector<const Exchange*>& used, std::int64_t base,
                                       const SlopeRange& allowed) {
  double st = 0, so = 0;
  for (const Exchange* x : used) {
    st += static_cast<double>(x->host_mid_ns - origin_ns_);
    so += static_cast<double>(x->offset_ns() - base);
  }
  const double n = static_cast<double>(used.size());
  const double mt = st / n, mo = so / n;
  double stt = 0, sto = 0;
  for (const Exchange* x : used) {
    const double dt = static_cast<double>(x->host_mid_ns - origin_ns_) - mt;
    stt += dt * dt;
    sto += dt * (static_cast<double>(x->offset_ns() - base) - mo);
  }
  b_ = std::clamp(stt > 0 ? sto / stt : 0.0, allowed.lo, allowed.hi);
  a_ns_ = static_cast<double>(base) + mo - b_ * mt;
}

std::int64_t RoundTripClock::to_host_ns(double remote_s) const {
  // offset depends on host time, which is what we solve for: host = remote + a + b (host - origin).
  const double remote_ns = remote_s * 1e9;
  const double host = (remote_ns + a_ns_ - b_ * static_cast<double>(origin_ns_)) / (1 - b_);
  return static_cast<std::int64_t>(std::llround(host));
}

std::int64_t RoundTripClock::offset_ns() const { return static_cast<std::int64_t>(std::llround(a_ns_)); }

std::optional<double> RoundTripClock::drift_ppm() const {
  if (!have_line_) return std::nullopt;
  return b_ * 1e6;
}

std::int64_t RoundTripClock::uncertainty_ns() const {
  std::int64_t best = std::numeric_limits<std::int64_t>::max();
  for (const Exchange& x : exchanges_) best = std::min(best, x.rtt_ns);
  return exchanges_.empty() ? 0 : best / 2;
}

}  // namespace fovea::trackerd
