#pragma once
// Which device point each cross-section of a vessel is pushed toward, for a vessel the
// device runs through (an iliac, from the femoral access to the aorta). The paper casts
// each ray from a section to its nearest device point; in a tortuous vessel that a stiff
// wire straightens, the nearest device point of a loop's sections is wherever the wire
// passes a crossing of the loop, so the loop is pushed onto the wire out of order and its
// length bulges out beside it (docs/DEFORMATION.md, "Ordered pairing"). Here sections and
// device points are paired in the order both run in, from the section at the foot of the
// device's proximal end (where it enters the vessel) distally, and where the device is
// shorter than the vessel's path, the partner's arc is the mean of the two limits of what
// a straightened vessel does with its excess length:
//   * it shortens where it was tortuous: each section goes the shortest way to the wire
//     (the arc of its nearest device point, made non-decreasing along the vessel);
//   * it keeps its length from the entry and slides along the wire (the device arc equals
//     the section's arc from the entry section).
// The device's distal end is open: the wire runs on to the access, mostly out of the field
// of view, so it is continued straight past its last point, and sections whose partner lies
// on that unseen continuation get none (rather than being crowded onto the last point seen).
// A device that reaches the vessel's end (its last point's foot within a skeleton spacing
// of the centerline's end: the access is in the model) holds that end instead: the sections
// past its length are paired with its last point.
#include <vector>

#include "evar/geometry/polyline.hpp"

namespace evar::deform {

struct SectionPartner {
  double section_arc_mm;  ///< along the vessel's centerline
  double device_arc_mm;   ///< along `device` as given to ordered_pairing
};

/// `device`: the device samples that belong to the vessel, in the device's order (either
/// end first; the proximal end is the one whose foot lies nearer the centerline's start).
/// Sections evenly spaced, at most `step_mm` apart, from the proximal end's foot toward the
/// centerline's end, as far as their partners lie on the device (to the end where the
/// device reaches it); ordered so that device
/// arcs are non-decreasing, from 0 to at most the device's length. Empty when the two
/// ends' feet lie less than four steps apart (a device that does not run along the
/// vessel) or fewer than five sections are paired: the nearest pairing applies there.
std::vector<SectionPartner> ordered_pairing(const geometry::Polyline& centerline, const geometry::Polyline& device,
                                            double step_mm);

/// The device's run through a vessel it enters at the proximal end (an iliac, entered from
/// the aorta at their junction): device samples every `step_mm` from the one nearest
/// `entry` (the junction where it is now, e.g. as the aorta's deformation moved it) toward
/// the device's end whose foot lies further along the centerline, while their feet stay on
/// the centerline. Far from the preoperative centerline (an iliac straightened, the pelvis
/// moved) the device still runs through the vessel: no distance decides what belongs to
/// it. Empty when the device's point nearest `entry` is one of its ends (it does not pass
/// the entry: it ends before the junction, or starts below it out of the field of view),
/// and for fewer than two samples.
geometry::Polyline device_run_from(const geometry::Polyline& centerline, const geometry::Polyline& device,
                                   const Eigen::Vector3d& entry, double step_mm);

/// ordered_pairing for such a run: its first point is the partner of the vessel's first
/// section (arc 0, the junction), sections every at most `step_mm` on from there.
std::vector<SectionPartner> ordered_pairing_from_entry(const geometry::Polyline& centerline, const geometry::Polyline& run,
                                                       double step_mm);

/// The inverse of a pairing: the section arc whose partner is `device_arc_mm`, interpolated
/// between neighbouring pairs, the middle of a run of sections sharing that partner, and
/// the first or last section beyond the pairs' device arcs. The same section whichever
/// end the device was given from.
double section_arc_of(const std::vector<SectionPartner>& pairs, double device_arc_mm);

}  // namespace evar::deform
