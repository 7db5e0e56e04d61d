#pragma once
// From a view pair to the adapted vessel model: the device triangulated from its two
// curves (in CT coordinates, through the registered projections), checked, and the scene
// deformed to contain it (paper 2.2-2.3).
#include <cstdint>
#include <stdexcept>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/two_view_reconstruction.hpp"
#include "evar/node/view_pair_selector.hpp"
#include "evar/overlay/frame_compositor.hpp"

namespace evar::node {

struct AdaptationOptions {
  geometry::ReconstructionOptions reconstruction;
  /// A device whose 3D curve projects farther than this from its 2D curves on average is
  /// a wrong match (two different wires, a false segmentation), not a measurement.
  double max_mean_residual_px = 4.0;
  double min_length_mm = 20.0;  ///< shorter reconstructions cannot place the vessels
  /// When the curves read two ways (a device symmetric about the views' epipolar
  /// geometry), the reading that runs outside the preoperative lumen by this much less
  /// (mean over its points) is the device; closer ones are refused as ambiguous. The
  /// device bends the vessels by a few mm, a wrong reading misses them by tens.
  double reading_margin_mm = 5.0;
  /// A device with more than `max_share_outside` of its points farther than
  /// `outside_limit_mm` outside every preoperative lumen is not this patient's device in
  /// these vessels but another structure the segmentation followed (an ECG lead, a second
  /// wire) or a wrong registration. The device bends the iliacs by a few tens of mm at most.
  double outside_limit_mm = 50.0;
  double max_share_outside = 0.2;
  /// A device farther than this outside the preoperative vessels on average is checked for
  /// a picture turned or mirrored against its projection (node::check_picture_orientation);
  /// nearer, it may be a device that bends the vessels that far (at the paper's difficulty
  /// the right way round lay up to 12.6 mm outside, docs/FORMATS.md, "Video mapping").
  double orientation_outside_mm = 15.0;
};

struct AdaptedModel {
  std::uint64_t frame_earlier = 0, frame_later = 0;
  geometry::Reconstruction reconstruction;  ///< CT LPS mm
  deform::SceneDeformation deformation;
  double reconstruct_ms = 0.0, deform_ms = 0.0;
};

/// Thrown when a pair gives no usable model; what() says why (for the screen and the log).
class AdaptationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the roadmap draws: the scene's vessels and landmarks, and, given a model, its
/// deformed vessels (same order), moved landmarks and reconstructed device.
overlay::RoadmapModel roadmap_model(const geometry::Scene& scene, const AdaptedModel* adapted);
/// Puts a model's deformed vessels, moved landmarks and device into a roadmap.
void show_adapted(overlay::RoadmapModel& roadmap, const AdaptedModel& adapted);

/// AdaptationError naming the first vessel vertex, landmark or device point that is not
/// finite: the last guard before a model reaches the screen (a NaN vertex would draw a
/// wrong roadmap as if it were right), whatever the solver below promised.
void check_finite(const AdaptedModel& model);

/// How far outside the preoperative vessels each point of a device lies: its distance to
/// the nearest centerline less the lumen radius there (the deformer's radius profile; no
/// mesh is searched, so this costs a few hundred point-to-polyline projections), 0 inside.
/// Past a centerline's end, its distance across the end's axis (the vessel goes on).
std::vector<double> outside_lumen_mm(const geometry::Polyline& device, const deform::SceneDeformer& deformer);
/// outside_lumen_mm's mean (infinite for an empty device).
double mean_outside_lumen_mm(const geometry::Polyline& device, const deform::SceneDeformer& deformer);

/// AdaptationError when more than options.max_share_outside of the device's points lie
/// farther than options.outside_limit_mm outside every preoperative lumen.
void check_in_the_vessels(const geometry::Polyline& device, const deform::SceneDeformer& deformer,
                          const AdaptationOptions& options);

/// Of several readings of a view pair (geometry::reconstruct_two_view_readings), the index
/// of the one in the vessels: the smallest mean_outside_lumen_mm, by at least `margin_mm`
/// less than every other. AdaptationError when none stands out.
std::size_t reading_in_the_vessels(const std::vector<geometry::Reconstruction>& readings,
                                   const deform::SceneDeformer& deformer, double margin_mm);

/// `previous`: the last model's deformation, to warm-start the solve (SceneDeformer::deform).
/// The result has passed check_finite.
AdaptedModel adapt_model(const deform::SceneDeformer& deformer, const ViewPair& pair, const AdaptationOptions& options,
                         const deform::SceneDeformation* previous = nullptr);

}  // namespace evar::node
