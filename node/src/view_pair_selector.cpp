#include "evar/node/view_pair_selector.hpp"

#include <stdexcept>

#include "evar/geometry/two_view_reconstruction.hpp"

namespace evar::node {

ViewPairSelector::ViewPairSelector(double min_separation_deg, ViewPairOptions options)
    : min_separation_deg_(min_separation_deg), options_(options) {
  if (!(options_.same_view_deg > 0 && options_.same_view_deg < min_separation_deg_ && min_separation_deg_ < 90) ||
      options_.max_views < 2 || options_.max_gap_ns <= 0 || options_.partner_failures < 1)
    throw std::invalid_argument(
        "view pairs: need 0 < same_view_deg < min_separation_deg < 90, max_views >= 2, a positive max_gap_ns and "
        "partner_failures >= 1");
}

void ViewPairSelector::failed(const CandidateId& earlier) {
  retry_ = true;
  if (failed_partner_ == earlier) {
    ++partner_failures_;
  } else {
    failed_partner_ = earlier;
    partner_failures_ = 1;
  }
}

void ViewPairSelector::succeeded(const CandidateId& earlier) {
  if (failed_partner_ == earlier) {
    failed_partner_.reset();
    partner_failures_ = 0;
  }
}

std::optional<ViewPair> ViewPairSelector::add(ViewCandidate candidate) {
  const auto separation = [&](const ViewCandidate& other) {
    return geometry::view_separation_deg(other.geometry.P_ct, candidate.geometry.P_ct);
  };
  // The device may have moved since: old views go, and all go when time went back.
  std::erase_if(views_, [&](const ViewCandidate& v) {
    return v.time_ns > candidate.time_ns || candidate.time_ns - v.time_ns > options_.max_gap_ns;
  });
  const bool same_as_current = !views_.empty() && separation(views_.back()) < options_.same_view_deg;
  if (same_as_current) {
    views_.back() = candidate;
  } else {
    // A view seen before (the C-arm came back) moves to the end with its new candidate.
    std::erase_if(views_, [&](const ViewCandidate& v) { return separation(v) < options_.same_view_deg; });
    views_.push_back(candidate);
    if (views_.size() > options_.max_views) views_.erase(views_.begin());
  }
  if (failed_partner_ && partner_failures_ >= options_.partner_failures) {
    std::erase_if(views_, [&](const ViewCandidate& v) { return v.id() == *failed_partner_ && v.id() != candidate.id(); });
    failed_partner_.reset();
    partner_failures_ = 0;
  }
  if (same_as_current && !retry_) return std::nullopt;
  // The partner: the newest earlier view far enough away.
  for (auto it = views_.rbegin() + 1; it != views_.rend(); ++it) {
    const double sep = separation(*it);
    if (sep >= min_separation_deg_ && sep <= 180.0 - min_separation_deg_) {
      retry_ = false;
      return ViewPair{*it, candidate, sep};
    }
  }
  return std::nullopt;
}

}  // namespace evar::node
