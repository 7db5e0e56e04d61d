#pragma once
// The paper's evaluation (Table 1) on recorded sessions with ground truth: the session's
// frames go through the node's own steps in order (candidates, view pairs, reconstruction,
// deformation), and in every settled frame from the first adapted model on, each
// landmark is projected from the preoperative (initial) and from the adapted model and
// compared with where the true ostium projects. Distances are in mm at the isocenter
// (pixels · spacing · SOD/SID); "vertical" is the image-row component, the paper's
// cranio-caudal error.
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <map>
#include <mutex>

#include <nlohmann/json.hpp>

#include "evar/geometry/pelvis_registration.hpp"
#include "evar/node/device_candidate.hpp"
#include "evar/node/live_node.hpp"
#include "evar/node/model_adaptation.hpp"
#include "evar/node/pelvis_tracker.hpp"
#include "evar/node/view_pair_selector.hpp"
#include "evar/session/session.hpp"

namespace evar::app {

struct EvaluationOptions {
  node::CandidateOptions candidate;
  node::ViewPairOptions pairs;
  node::AdaptationOptions adaptation;
  deform::DeformOptions deform;
  /// As the live node: the pelvis found in the fluoroscopy (when the scene has its bones)
  /// and the models moved with it before they are bent (node/pelvis_tracker.hpp); disabled:
  /// the models where the registration put them.
  node::PelvisTrackingOptions pelvis;
};

struct LandmarkError {
  std::string label;
  std::string vessel;  ///< the vessel it sits on (nearest surface, as the deformation binds it)
  bool on_device_vessel = false;  ///< on an iliac the true device runs in (the paper's Table 1 measures these)
  int frames = 0;  ///< frames it was measured in
  double initial_mm = 0, adapted_mm = 0;                    ///< mean Euclidean distance over those frames
  double initial_vertical_mm = 0, adapted_vertical_mm = 0;  ///< mean |row difference|
};

/// Sums landmark distances frame by frame (the per-frame step of the evaluation, shared
/// with `evarnode run` on sessions with ground truth).
class OstiumErrors {
 public:
  /// The preoperative landmarks (CT LPS mm, labelled as in the truth) and where the true
  /// ostia project, frame by frame.
  OstiumErrors(std::vector<geometry::ControlPoint> initial, const std::vector<session::OstiumTruth>& truth);
  /// One frame (its number in the session): its projection, mm at the isocenter per pixel
  /// and the adapted landmarks (same order as the initial ones). True when at least one
  /// landmark was measured.
  bool add(std::int64_t frame, const geometry::ProjectionMatrix& P_ct, double mm_per_px,
           const std::vector<geometry::ControlPoint>& adapted);
  /// The means per landmark (only those measured), by label.
  std::vector<LandmarkError> result() const;

 private:
  struct Sums {
    int frames = 0;
    double initial = 0, adapted = 0, initial_v = 0, adapted_v = 0;
  };
  std::vector<geometry::ControlPoint> initial_;
  std::multimap<std::int64_t, session::OstiumTruth> truth_;
  std::map<std::string, Sums> sums_;
};

/// A reconstructed device against the session's true device, in 3D (CT LPS): the distance
/// of each reconstructed point to the true curve. It separates the reconstruction's share
/// of the ostium errors from the deformation's.
struct DeviceError {
  std::uint64_t frame_earlier = 0, frame_later = 0;  ///< the view pair
  double mean_mm = 0.0, max_mm = 0.0;
  /// How much of the true device the reconstruction spans: the true curve's arc length between
  /// the feet of the reconstructed points lying within 3 mm of it, and the true curve's length.
  double covered_mm = 0.0, true_length_mm = 0.0;
};

/// DeviceError of `reconstructed` against the polyline `truth` (both CT LPS mm).
DeviceError device_error(const geometry::Polyline& reconstructed, const geometry::Polyline& truth);

struct CaseEvaluation {
  std::filesystem::path session;
  std::size_t frames = 0, candidates = 0, pairs = 0, adaptations = 0;
  std::vector<std::string> failures;  ///< why pairs gave no model
  std::size_t frames_evaluated = 0;
  std::vector<LandmarkError> landmarks;  ///< only those measured
  std::vector<DeviceError> devices;      ///< each adapted model's reconstruction against the true device
  std::string device_iliac;              ///< the iliac the true device runs in ("" if none)
  std::string physics = "unknown";       ///< the simulator's truth physics (patient.json), if any
  std::string difficulty = "unknown";    ///< the simulator's difficulty (patient.json), if any
  double registration_residual_deg = 0.0;  ///< the given registration's rotation off the true one
  /// The last pelvis registration tried (from the fluoroscopy views seen so far); none when
  /// the scene has no pelvis, EvaluationOptions::pelvis is disabled or fewer than two views came.
  std::optional<geometry::PelvisRegistration> pelvis;
  std::shared_ptr<const node::AdaptedModel> model;  ///< the last adapted model (null when none)
  geometry::Polyline true_device;  ///< the session's true device in the node's CT frame (LPS mm)
  std::shared_ptr<const session::Session> recording;  ///< as read (for pictures)
  std::shared_ptr<const geometry::Scene> scene;   ///< as loaded (for pictures)
  std::size_t snapshot_frame = 0;       ///< index of the last evaluated frame (for pictures)
  double seconds = 0.0;
};

/// Throws base::InputError for a session without ground truth or with unreadable
/// files. `progress(done, total)` after each frame.
CaseEvaluation evaluate_session(const std::filesystem::path& session, const EvaluationOptions& options = {},
                                const std::function<void(std::size_t, std::size_t)>& progress = {});

/// An output sink that measures, frame by frame as the node shows them, the distances in
/// the frames composited with an adapted model, on a replay of `session` (sequence n is the
/// session's frame (n − 1) modulo its length). It keeps sums, not frames or models, so a
/// replay looped for hours runs in constant memory. The session must have ground truth.
class EvaluationSink final : public node::OutputSink {
 public:
  EvaluationSink(const session::Session& session, const geometry::Scene& scene);
  std::string name() const override { return "evaluation"; }
  void write(const node::ComposedFrame& frame) override;
  /// The means per landmark so far (only those measured).
  std::vector<LandmarkError> result() const;
  /// Frames measured so far.
  std::size_t frames() const;

 private:
  const session::Session& session_;
  mutable std::mutex mutex_;
  OstiumErrors errors_;
  std::size_t frames_ = 0;
};

/// {"label", "frames", "initial_mm", "adapted_mm", "initial_vertical_mm", "adapted_vertical_mm"}.
nlohmann::json to_json(const LandmarkError& l);

struct Statistic {
  double mean = 0, sd = 0, median = 0;
  std::size_t n = 0;
};
/// Sample mean, standard deviation (n − 1) and median; zeros for no values.
Statistic statistic(std::vector<double> values);

/// One measure (e.g. &LandmarkError::adapted_mm) of every landmark of every case; with
/// `device_vessel_only`, of the landmarks on an iliac carrying the device only.
std::vector<double> landmark_values(const std::vector<CaseEvaluation>& cases, double LandmarkError::*measure,
                                    bool device_vessel_only = false);

}  // namespace evar::app
