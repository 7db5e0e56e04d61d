#pragma once
// Which frames the device is reconstructed from. A candidate is a frame taken with the beam
// on and the C-arm still in which a device was segmented. Candidates are grouped by view
// (angulations within `same_view_deg`); the newest candidate of each view is kept. The first
// candidate after the C-arm went to another view makes a pair with the newest candidate of
// the most recent view at least the reconstruction's minimum separation away
// (geometry::ReconstructionOptions::min_separation_deg): a view pair, reconstructed and
// adapted to in the background. Newer pairs supersede older ones; views older than
// ViewPairOptions::max_gap_ns are not paired. A partner frame that failed repeatedly is
// forgotten.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "evar/node/frame_view.hpp"

namespace evar::node {

/// Which frame a candidate is: its number with its time, since a source that reconnects
/// (a camera restarted, a grabber plugged back) numbers its frames from the start again.
struct CandidateId {
  std::uint64_t frame = 0;
  std::int64_t time_ns = 0;
  bool operator==(const CandidateId&) const = default;
};

struct ViewCandidate {
  std::uint64_t frame = 0;              ///< the frame's sequence number (as the source numbers it)
  std::int64_t time_ns = 0;             ///< the frame's time (any one clock for all candidates)
  FrameView geometry;
  std::vector<Eigen::Vector2d> curve_px;  ///< the segmented device, tip first
  CandidateId id() const { return {frame, time_ns}; }
};

struct ViewPair {
  ViewCandidate earlier, later;
  double separation_deg = 0.0;
};

struct ViewPairOptions {
  double same_view_deg = 2.0;        ///< candidates closer than this are one view
  std::size_t max_views = 8;         ///< views remembered (the oldest is forgotten)
  /// Two views are reconstructed as one device only if it did not move in between: a view
  /// older than this (by candidate time) is forgotten. Turning the C-arm to a second view
  /// takes seconds; two minutes leave room for a pause, not for the next step of the
  /// procedure. A candidate older than the ones remembered (a clock or a replay that
  /// started over) forgets them all.
  std::int64_t max_gap_ns = 120'000'000'000;
  /// Pairs that failed in a row with the same partner frame before that frame is forgotten:
  /// the newer frames of the current view were tried against it, so the fault is likely
  /// the partner's (a false segmentation), and an older view may pair instead.
  int partner_failures = 2;
};

class ViewPairSelector {
 public:
  /// `min_separation_deg`: views closer than this cannot be reconstructed from (the
  /// reconstruction's own limit). std::invalid_argument unless
  /// 0 < same_view_deg < min_separation_deg < 90 and max_views >= 2.
  explicit ViewPairSelector(double min_separation_deg, ViewPairOptions options = {});

  /// Takes a candidate; returns the pair it completes, if any.
  std::optional<ViewPair> add(ViewCandidate candidate);
  /// A pair whose earlier candidate was `earlier` could not be used (reconstruction
  /// failed): the next candidate of the current view tries again with its newer frame;
  /// after ViewPairOptions::partner_failures such failures in a row with that partner,
  /// with the next older view far enough.
  void failed(const CandidateId& earlier);
  /// A pair with that earlier candidate was used: its failures so far no longer count.
  void succeeded(const CandidateId& earlier);

 private:
  double min_separation_deg_;
  ViewPairOptions options_;
  std::vector<ViewCandidate> views_;  // newest candidate per view, most recent view last
  bool retry_ = false;
  std::optional<CandidateId> failed_partner_;  // the earlier candidate of the failures in a row counted here
  int partner_failures_ = 0;
};

}  // namespace evar::node
