#include "session_evaluation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>

#include "evar/geometry/input_error.hpp"
#include "evar/geometry/scene.hpp"
#include "evar/sim/session.hpp"
#include "evar/sim/session_replay.hpp"

namespace evar::app {

bool OstiumErrors::add(const geometry::ProjectionMatrix& P_ct, double mm_per_px,
                       const std::vector<geometry::ControlPoint>& adapted, const std::vector<sim::OstiumTruth>& truth) {
  bool any = false;
  for (const sim::OstiumTruth& t : truth)
    for (std::size_t k = 0; k < initial_.size() && k < adapted.size(); ++k) {
      if (initial_[k].label != t.label) continue;
      const auto before = geometry::project(P_ct, initial_[k].position_lps);
      const auto after = geometry::project(P_ct, adapted[k].position_lps);
      if (!before || !after) continue;
      auto it = std::find_if(sums_.begin(), sums_.end(), [&](const auto& s) { return s.first == t.label; });
      if (it == sums_.end()) it = sums_.insert(sums_.end(), {t.label, Sums{}});
      Sums& s = it->second;
      ++s.frames;
      s.initial += (*before - t.pixel).norm() * mm_per_px;
      s.adapted += (*after - t.pixel).norm() * mm_per_px;
      s.initial_v += std::abs(before->y() - t.pixel.y()) * mm_per_px;
      s.adapted_v += std::abs(after->y() - t.pixel.y()) * mm_per_px;
      any = true;
    }
  return any;
}

std::vector<LandmarkError> OstiumErrors::result() const {
  std::vector<LandmarkError> out;
  for (const auto& [label, s] : sums_)
    out.push_back({label, s.frames, s.initial / s.frames, s.adapted / s.frames, s.initial_v / s.frames,
                   s.adapted_v / s.frames});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.label < b.label; });
  return out;
}

CaseEvaluation evaluate_session(const std::filesystem::path& directory, const EvaluationOptions& options,
                                const std::function<void(std::size_t, std::size_t)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  const sim::Session session = sim::read_session(directory);
  if (!session.truth)
    throw geometry::InputError((directory / "session.json").string() +
                               ": ground_truth: missing (evaluation needs the true ostia)");
  const geometry::Scene scene = geometry::load_scene(directory / session.scene);
  if (scene.landmarks.empty())
    throw geometry::InputError(scene.file.string() + ": landmarks: none (nothing to evaluate)");
  deform::DeformOptions deform_options = options.deform;
  const deform::SceneDeformer deformer(scene, deform_options);

  std::multimap<std::int64_t, const sim::OstiumTruth*> truth_by_frame;
  for (const auto& o : session.truth->ostia) truth_by_frame.emplace(o.frame, &o);

  CaseEvaluation result;
  result.session = directory;
  result.frames = session.frames.size();
  ViewPairSelector selector(options.pairs);
  std::shared_ptr<const AdaptedModel> model;
  OstiumErrors errors(scene.landmarks);
  for (std::size_t i = 0; i < session.frames.size(); ++i) {
    const sim::FrameRecord& record = session.frames[i];
    const sim::CArmSample* sample = sim::carm_at(session, record.timestamp_ns);
    if (sample == nullptr || sample->moving || !sample->fluoro_on) {
      if (progress) progress(i + 1, session.frames.size());
      continue;
    }
    const FrameView view = frame_view(session.detector, session.ct_to_carm,
                                      sim::to_carm_state(*sample, 0));
    const cv::Mat image = sim::read_session_frame(session, i);
    FrameAnalysis analysis = analyse_frame(image, view, options.candidate);
    if (analysis.candidate) {
      ++result.candidates;
      ViewCandidate c{static_cast<std::uint64_t>(record.frame), record.timestamp_ns, view,
                      std::move(analysis.curve.points), analysis.curve.confidence};
      if (auto pair = selector.add(std::move(c))) {
        ++result.pairs;
        try {
          model = std::make_shared<const AdaptedModel>(
              adapt_model(deformer, *pair, options.adaptation, model ? &model->deformation : nullptr));
          ++result.adaptations;
        } catch (const AdaptationError& e) {
          result.failures.push_back("frames " + std::to_string(pair->earlier.frame) + "+" +
                                    std::to_string(pair->later.frame) + ": " + e.what());
          selector.retry();
        }
      }
    }
    if (model) {
      std::vector<sim::OstiumTruth> truth;
      const auto [lo, hi] = truth_by_frame.equal_range(record.frame);
      for (auto it = lo; it != hi; ++it) truth.push_back(*it->second);
      if (errors.add(view.P_ct, mm_at_isocenter_per_px(view.view), model->deformation.landmarks, truth)) {
        ++result.frames_evaluated;
        result.snapshot_frame = i;
      }
    }
    if (progress) progress(i + 1, session.frames.size());
  }
  result.landmarks = errors.result();
  result.model = model;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
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

}  // namespace evar::app
