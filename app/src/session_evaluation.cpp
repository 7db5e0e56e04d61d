#include "session_evaluation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>

#include "evar/node/pelvis_tracker.hpp"
#include "evar/geometry/video_frame.hpp"
#include "evar/node/frame_view.hpp"
#include "evar/node/logging.hpp"

#include <Eigen/Geometry>
#include <numbers>

#include "evar/base/input_error.hpp"
#include "evar/geometry/json_fields.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/session/session.hpp"
#include "evar/session/session_replay.hpp"

namespace evar::app {

OstiumErrors::OstiumErrors(std::vector<geometry::ControlPoint> initial, const std::vector<session::OstiumTruth>& truth)
    : initial_(std::move(initial)) {
  for (const auto& t : truth) truth_.emplace(t.frame, t);
}

bool OstiumErrors::add(std::int64_t frame, const geometry::ProjectionMatrix& P_ct, double mm_per_px,
                       const std::vector<geometry::ControlPoint>& adapted) {
  bool any = false;
  const auto [lo, hi] = truth_.equal_range(frame);
  for (auto it = lo; it != hi; ++it) {
    const session::OstiumTruth& t = it->second;
    for (std::size_t k = 0; k < initial_.size() && k < adapted.size(); ++k) {
      if (initial_[k].label != t.label) continue;
      const auto before = geometry::project(P_ct, initial_[k].position_lps);
      const auto after = geometry::project(P_ct, adapted[k].position_lps);
      if (!before || !after) continue;
      Sums& s = sums_[t.label];
      ++s.frames;
      s.initial += (*before - t.pixel).norm() * mm_per_px;
      s.adapted += (*after - t.pixel).norm() * mm_per_px;
      s.initial_v += std::abs(before->y() - t.pixel.y()) * mm_per_px;
      s.adapted_v += std::abs(after->y() - t.pixel.y()) * mm_per_px;
      any = true;
    }
  }
  return any;
}

std::vector<LandmarkError> OstiumErrors::result() const {
  std::vector<LandmarkError> out;
  for (const auto& [label, s] : sums_) {
    LandmarkError l;
    l.label = label;
    l.frames = s.frames;
    l.initial_mm = s.initial / s.frames;
    l.adapted_mm = s.adapted / s.frames;
    l.initial_vertical_mm = s.initial_v / s.frames;
    l.adapted_vertical_mm = s.adapted_v / s.frames;
    out.push_back(std::move(l));
  }
  return out;
}

DeviceError device_error(const geometry::Polyline& reconstructed, const geometry::Polyline& truth) {
  if (reconstructed.empty() || truth.size() < 2)
    throw std::invalid_argument("device_error: needs reconstructed points and a true curve of 2 or more points");
  DeviceError e;
  const geometry::PolylineProjector onto_truth(truth);
  double first_arc = std::numeric_limits<double>::infinity(), last_arc = -first_arc;
  for (const Eigen::Vector3d& p : reconstructed) {
    const geometry::PolylineProjection foot = onto_truth.project(p);
    e.mean_mm += foot.distance_mm;
    e.max_mm = std::max(e.max_mm, foot.distance_mm);
    if (foot.distance_mm <= 3.0) {
      first_arc = std::min(first_arc, foot.arc_length_mm);
      last_arc = std::max(last_arc, foot.arc_length_mm);
    }
  }
  e.mean_mm /= static_cast<double>(reconstructed.size());
  e.covered_mm = last_arc >= first_arc ? last_arc - first_arc : 0.0;
  e.true_length_mm = geometry::arc_lengths(truth).back();
  return e;
}

CaseEvaluation evaluate_session(const std::filesystem::path& directory, const EvaluationOptions& options,
                                const std::function<void(std::size_t, std::size_t)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  auto recording = std::make_shared<const session::Session>(session::read_session(directory));
  const session::Session& session = *recording;
  if (!session.truth)
    throw base::InputError((directory / "session.json").string() +
                               ": ground_truth: missing (evaluation needs the true ostia)");
  auto loaded = std::make_shared<const geometry::Scene>(geometry::load_scene(directory / session.scene));
  const geometry::Scene& scene = *loaded;
  if (scene.landmarks.empty())
    throw base::InputError(scene.file.string() + ": landmarks: none (nothing to evaluate)");
  // The models the node bends: where the registration put them, or, once the pelvis has been
  // found in two views, moved with it (made anew each time the pelvis is found elsewhere), as
  // the live node does (node/pelvis_tracker.hpp).
  const deform::SceneDeformer registered(scene, options.deform);
  node::PelvisTracker pelvis(scene, options.pelvis, options.deform);
  std::shared_ptr<const node::PelvisMovedModels> moved;
  const deform::SceneDeformer* deformer = &registered;
  bool deformer_changed = false;
  std::optional<node::ViewPair> shown_pair;  // the pair the model came from
  geometry::Polyline true_device;
  for (const auto& p : geometry::read_curve(directory / session.truth->device, 2).points) true_device.push_back(p.position_lps);
  // Where the registration given to the node is off (sessions at the paper's difficulty),
  // the true device is compared in the node's CT frame: x_node = given⁻¹ · true · x.
  CaseEvaluation result;
  if (session.truth->ct_to_carm) {
    const Eigen::Matrix4d M = session.ct_to_carm.inverse() * *session.truth->ct_to_carm;
    for (auto& p : true_device) p = M.topLeftCorner<3, 3>() * p + M.topRightCorner<3, 1>();
    const Eigen::AngleAxisd turn(Eigen::Matrix3d(M.topLeftCorner<3, 3>()));
    result.registration_residual_deg = turn.angle() * 180.0 / std::numbers::pi;
  }
  // The simulator's description of the case, when the scene is a synthetic patient's.
  // A patient.json that cannot be read only leaves the case unlabelled ("unknown").
  if (const auto patient = (directory / session.scene).parent_path() / "patient.json"; std::filesystem::is_regular_file(patient)) {
    try {
      const nlohmann::json j = geometry::detail::parse_json_file(patient);
      result.difficulty = j.value("difficulty", "mild");
      if (j.contains("ground_truth") && j["ground_truth"].is_object()) result.physics = j["ground_truth"].value("physics", "beam");
    } catch (const std::exception&) {
      result.difficulty = result.physics = "unknown";
    }
  }

  result.session = directory;
  result.frames = session.frames.size();
  node::ViewPairSelector selector(options.adaptation.reconstruction.min_separation_deg, options.pairs);
  std::shared_ptr<const node::AdaptedModel> model;
  OstiumErrors errors(scene.landmarks, session.truth->ostia);
  // Frames that are the monitor's picture (or a zoom mode's turned, flipped or round image):
  // the device is searched for where they show the field. One set of masks per zoom mode.
  std::map<int, node::CandidateOptions> candidates;
  const auto candidate_for = [&](const session::CArmSample& sample) -> const node::CandidateOptions& {
    const geometry::ZoomMode* zoom = session::zoom_mode_of(session, sample);
    const int key = zoom ? zoom->number : 0;
    if (const auto it = candidates.find(key); it != candidates.end()) return it->second;
    node::CandidateOptions c = options.candidate;
    const auto mapping = zoom ? geometry::frame_mapping(session.video_mapping, *zoom) : session.video_mapping;
    if (mapping) {
      const geometry::VideoToDetector map(*mapping, zoom ? zoom->cols : session.detector.cols,
                                          zoom ? zoom->rows : session.detector.rows);
      c.field_mask = geometry::detector_field_mask(*mapping, map);
      c.hidden_mask = geometry::detector_text_mask(*mapping, map);
    }
    return candidates.emplace(key, std::move(c)).first->second;
  };
  std::size_t zoom_unknown = 0;
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const session::FrameRecord& record = session.frames[i];
    const session::CArmSample* sample = session::carm_at(session, record.timestamp_ns);
    // A zoom mode the session does not list: the frame's pixels are unknown (counted, said below).
    const bool field_known = sample != nullptr && session::zoom_known(session, *sample);
    if (sample != nullptr && !field_known) ++zoom_unknown;
    if (!field_known || sample->moving || !sample->fluoro_on) {
      if (progress) progress(i + 1, session.frames.size());
      continue;
    }
    const node::FrameView view =
        node::frame_view(session::view_of(session, *sample), session.ct_to_carm, session::to_carm_state(*sample, 0));
    const node::CandidateOptions& candidate = candidate_for(*sample);
    const cv::Mat image = session::read_detector_frame(session, i);
    // As the node: a video-out frame whose image area is not fluoroscopy is not searched.
    node::FrameAnalysis analysis;
    if (session.video_mapping) analysis.reason = geometry::not_fluoroscopy(image, candidate.field_mask);
    // The pelvis: the first fluoroscopy frame of every view is one more view of its bones.
    if (analysis.reason.empty() &&
        pelvis.offer(image, view, "frame " + std::to_string(record.frame) + ", " +
                                      node::angulation_text(sample->primary_deg, sample->secondary_deg))) {
      // The report keeps the pose the models were moved by; a later refusal only replaces a refusal.
      const geometry::PelvisRegistration found = pelvis.register_views();
      if (found.found || !result.pelvis || !result.pelvis->found) result.pelvis = found;
      if (pelvis.moves_models(found)) {
        try {
          moved = pelvis.move_models(found);
          deformer = moved->deformer.get();
          deformer_changed = true;
        } catch (const std::exception& e) {
          result.pelvis->found = false;
          result.pelvis->refused = std::string("found, but the models cannot move with it: ") + e.what();
        }
        // As the node: the model on screen is adapted again from the moved models (kept as
        // it was when that fails, as the node keeps its last good model).
        if (deformer_changed && model && shown_pair) {
          try {
            model = std::make_shared<const node::AdaptedModel>(node::adapt_model(*deformer, *shown_pair, options.adaptation));
            deformer_changed = false;
          } catch (const node::AdaptationError&) {
          }
        }
      }
    }
    if (analysis.reason.empty()) analysis = node::analyse_frame(image, view, candidate);
    if (analysis.candidate) {
      ++result.candidates;
      node::ViewCandidate c{static_cast<std::uint64_t>(record.frame), record.timestamp_ns, view,
                      std::move(analysis.curve.points)};
      if (auto pair = selector.add(std::move(c))) {
        ++result.pairs;
        try {
          model = std::make_shared<const node::AdaptedModel>(
              node::adapt_model(*deformer, *pair, options.adaptation,
                                model && !deformer_changed ? &model->deformation : nullptr));
          deformer_changed = false;
          shown_pair = *pair;
          ++result.adaptations;
          selector.succeeded(pair->earlier.id());
          DeviceError e = device_error(model->reconstruction.points, true_device);
          e.frame_earlier = pair->earlier.frame;
          e.frame_later = pair->later.frame;
          result.devices.push_back(e);
        } catch (const node::AdaptationError& e) {
          result.failures.push_back("frames " + std::to_string(pair->earlier.frame) + "+" +
                                    std::to_string(pair->later.frame) + ": " + e.what());
          selector.failed(pair->earlier.id());
        }
      }
    }
    if (model) {
      if (errors.add(record.frame, view.P_ct, node::mm_at_isocenter_per_px(view.view), model->deformation.landmarks)) {
        ++result.frames_evaluated;
        result.snapshot_frame = i;
      }
    }
    if (progress) progress(i + 1, session.frames.size());
  }
  result.landmarks = errors.result();
  if (zoom_unknown > 0)
    node::log().warn("{}: {} frames were taken in a zoom mode session.json does not list and were not evaluated",
                     directory.string(), zoom_unknown);
  // Which iliac the true device runs in (the deformation's own rule, on the true device),
  // and which vessel each landmark sits on: the paper's Table 1 measures the internal iliac
  // ostia of iliacs carrying a device.
  try {
    const deform::SceneDeformation on_truth = deformer->deform(true_device);
    result.device_iliac = on_truth.device_iliac;
    for (LandmarkError& l : result.landmarks)
      for (std::size_t k = 0; k < scene.landmarks.size(); ++k)
        if (scene.landmarks[k].label == l.label) l.vessel = on_truth.landmark_vessel[k];
  } catch (const std::exception&) {
    result.device_iliac.clear();  // a truth the deformation refuses carries no iliac here
  }
  for (LandmarkError& l : result.landmarks)
    l.on_device_vessel = !result.device_iliac.empty() && l.vessel == result.device_iliac;
  result.model = model;
  result.true_device = std::move(true_device);
  result.recording = std::move(recording);
  result.scene = std::move(loaded);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

namespace {
const std::vector<session::OstiumTruth>& ostia_of(const session::Session& session) {
  if (!session.truth || session.frames.empty())
    throw std::invalid_argument("the evaluation needs a session with frames and ground truth");
  return session.truth->ostia;
}
}  // namespace

EvaluationSink::EvaluationSink(const session::Session& session, const geometry::Scene& scene)
    : session_(session), errors_(scene.landmarks, ostia_of(session)) {}

void EvaluationSink::write(const node::ComposedFrame& e) {
  if (e.held || !e.detector_view || !e.model || !e.model->adapted || e.sequence == 0) return;
  const session::FrameRecord& record = session_.frames[(e.sequence - 1) % session_.frames.size()];
  std::lock_guard lock(mutex_);
  // On the detector, as the truth is: the same figures whether the frames were the
  // detector's or the monitor's picture of it.
  const node::FrameView& view = *e.detector_view;
  if (errors_.add(record.frame, view.P_ct, node::mm_at_isocenter_per_px(view.view), e.model->adapted->deformation.landmarks))
    ++frames_;
}

std::vector<LandmarkError> EvaluationSink::result() const {
  std::lock_guard lock(mutex_);
  return errors_.result();
}

std::size_t EvaluationSink::frames() const {
  std::lock_guard lock(mutex_);
  return frames_;
}

nlohmann::json to_json(const LandmarkError& l) {
  return {{"label", l.label},
          {"vessel", l.vessel},
          {"on_device_vessel", l.on_device_vessel},
          {"frames", l.frames},
          {"initial_mm", l.initial_mm},
          {"adapted_mm", l.adapted_mm},
          {"initial_vertical_mm", l.initial_vertical_mm},
          {"adapted_vertical_mm", l.adapted_vertical_mm}};
}

Statistic statistic(std::vector<double> values) {
  Statistic s;
  s.n = values.size();
  if (values.empty()) return s;
  s.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(s.n);
  double ss = 0;
  for (double v : values) ss += (v - s.mean) * (v - s.mean);
  s.sd = s.n > 1 ? std::sqrt(ss / static_cast<double>(s.n - 1)) : 0.0;
  std::sort(values.begin(), values.end());
  s.median = s.n % 2 ? values[s.n / 2] : 0.5 * (values[s.n / 2 - 1] + values[s.n / 2]);
  return s;
}

std::vector<double> landmark_values(const std::vector<CaseEvaluation>& cases, double LandmarkError::*measure,
                                    bool device_vessel_only) {
  std::vector<double> values;
  for (const auto& c : cases)
    for (const auto& l : c.landmarks)
      if (!device_vessel_only || l.on_device_vessel) values.push_back(l.*measure);
  return values;
}

}  // namespace evar::app
