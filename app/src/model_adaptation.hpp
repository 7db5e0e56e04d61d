#pragma once
// From a view pair to the adapted vessel model: the device triangulated from its two
// curves (in CT coordinates, through the registered projections), checked, and the scene
// deformed to contain it (paper 2.2-2.3).
#include <cstdint>
#include <stdexcept>

#include "evar/deform/scene_deformation.hpp"
#include "evar/geometry/two_view_reconstruction.hpp"
#include "evar/overlay/frame_compositor.hpp"
#include "view_pair_selector.hpp"

namespace evar::app {

struct AdaptationOptions {
  geometry::ReconstructionOptions reconstruction;
  /// A device whose 3D curve projects farther than this from its 2D curves on average is
  /// a wrong match (two different wires, a false segmentation), not a measurement.
  double max_mean_residual_px = 4.0;
  double min_length_mm = 20.0;  ///< shorter reconstructions cannot place the vessels
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

/// `previous`: the last model's deformation, to warm-start the solve (SceneDeformer::deform).
/// The result has passed check_finite.
AdaptedModel adapt_model(const deform::SceneDeformer& deformer, const ViewPair& pair, const AdaptationOptions& options,
                         const deform::SceneDeformation* previous = nullptr);

}  // namespace evar::app
