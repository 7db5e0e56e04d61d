#pragma once
// Which device point each cross-section of a vessel is pushed toward, for a vessel the
// device runs through (an iliac, from the femoral access to the aorta). The paper casts
// each ray from a section to its nearest device point; in a tortuous vessel that a stiff
// wire straightens, the nearest device point of a loop's sections is wherever the wire
// passes a crossing of the loop, so the loop is pushed onto the wire out of order and its
// length bulges out beside it (docs/DEFORMATION.md, "Ordered pairing"). Here sections and
// device points are paired in the order both run in, every section between the first and
// the last device point's foot gets a partner, and where the device is shorter than the
// vessel's path between them, the partner's arc is the mean of the two limits of what a
// straightened vessel does with its excess length:
//   * it shortens where it was tortuous: each section goes the shortest way to the wire
//     (the arc of its nearest device point, made non-decreasing along the vessel);
//   * it keeps its length from the proximal end and slides along the wire (the device arc
//     equals the section's arc from the proximal section, clamped to the device's length).
#include <vector>

#include "evar/geometry/polyline.hpp"

namespace evar::deform {

struct SectionPartner {
  double section_arc_mm;  ///< along the vessel's centerline
  double device_arc_mm;   ///< along `device` as given to ordered_pairing
};

/// `device`: the device samples that belong to the vessel, in the device's order (either
/// end first); sections evenly spaced, at most `step_mm` apart, from the foot of its first sample to the foot of its
/// last, in that order; device arcs non-decreasing along them, from 0 to at most the
/// device's length. Empty when the feet lie less than four steps apart (a device that
/// does not run along the vessel): the nearest pairing applies there.
std::vector<SectionPartner> ordered_pairing(const geometry::Polyline& centerline, const geometry::Polyline& device,
                                            double step_mm);

/// The inverse of a pairing: the section arc whose partner is `device_arc_mm`, interpolated
/// between neighbouring pairs, the middle of a run of sections sharing that partner, and
/// the first or last section beyond the pairs' device arcs. The same section whichever
/// end the device was given from.
double section_arc_of(const std::vector<SectionPartner>& pairs, double device_arc_mm);

}  // namespace evar::deform
