// `evarnode eval`: the paper's Table 1 on sessions with ground truth (session_evaluation.hpp):
// eval.json, eval.md and the pictures (evaluation_plots.hpp) in --out.
#include <Eigen/Geometry>
#include <algorithm>
#include <numbers>
#include <cstdio>
#include <map>
#include <sstream>

#include "commands.hpp"
#include "evaluation_plots.hpp"
#include "evar/geometry/markups.hpp"
#include "evar/node/logging.hpp"
#include "json_file.hpp"
#include "progress_bar.hpp"
#include "session_evaluation.hpp"

namespace evar::app {

namespace {

struct Metric {
  const char* name;
  double LandmarkError::*initial;
  double LandmarkError::*adapted;
};
constexpr Metric kMetrics[] = {{"euclidean", &LandmarkError::initial_mm, &LandmarkError::adapted_mm},
                               {"vertical", &LandmarkError::initial_vertical_mm, &LandmarkError::adapted_vertical_mm}};

nlohmann::json to_json(const Statistic& s) {
  return {{"mean_mm", s.mean}, {"sd_mm", s.sd}, {"median_mm", s.median}, {"n", s.n}};
}

std::string fmt(const Statistic& s) {
  char b[64];
  std::snprintf(b, sizeof b, "%.2f ± %.2f (median %.2f)", s.mean, s.sd, s.median);
  return b;
}

// The table over `cases`: every landmark, the paper's protocol (the internal iliac ostia of
// iliacs carrying the device) and the reconstruction's share; into `summary` and `md`.
void summarize(const std::vector<CaseEvaluation>& cases, nlohmann::json& summary, std::ostringstream& md) {
  md << "| distance | initial (mm) | adapted (mm) |\n|---|---|---|\n";
  std::size_t without_model = 0;
  for (const auto& c : cases) without_model += c.model ? 0 : 1;
  for (const Metric& m : kMetrics) {
    const Statistic si = statistic(landmark_values(cases, m.initial)), sa = statistic(landmark_values(cases, m.adapted));
    summary[m.name] = {{"initial", to_json(si)}, {"adapted", to_json(sa)}};
    md << "| " << m.name << " | " << fmt(si) << " | " << fmt(sa) << " |\n";
  }
  // The paper's protocol: the internal iliac ostia of iliacs a device runs in.
  for (const Metric& m : kMetrics) {
    const Statistic si = statistic(landmark_values(cases, m.initial, true)),
                    sa = statistic(landmark_values(cases, m.adapted, true));
    if (si.n == 0) continue;
    summary["device_iliac_ostia"][m.name] = {{"initial", to_json(si)}, {"adapted", to_json(sa)}};
    md << "| " << m.name << ", ostia on the iliac carrying the device (the paper's Table 1) | " << fmt(si) << " | "
       << fmt(sa) << " |\n";
  }
  md << "\n" << cases.size() << " sessions, " << cases.size() - without_model
     << " with an adapted model; one value per landmark and session (its mean over the evaluated frames).\n";
  // The reconstruction's own share: each model's device against the true one, in 3D.
  std::vector<double> device_means, covered_mm, covered_percent;
  double device_worst = 0.0;
  for (const auto& c : cases)
    for (const DeviceError& e : c.devices) {
      device_means.push_back(e.mean_mm);
      device_worst = std::max(device_worst, e.max_mm);
      covered_mm.push_back(e.covered_mm);
      covered_percent.push_back(e.true_length_mm > 0.0 ? 100.0 * e.covered_mm / e.true_length_mm : 0.0);
    }
  if (!device_means.empty()) {
    const Statistic sd = statistic(device_means), sc = statistic(covered_mm), sp = statistic(covered_percent);
    summary["device_reconstruction"] = {{"mean_mm", sd.mean},     {"sd_mm", sd.sd},
                                        {"median_mm", sd.median}, {"models", sd.n},
                                        {"worst_point_mm", device_worst},
                                        {"covered_mm", {{"mean", sc.mean}, {"median", sc.median}}},
                                        {"covered_percent", {{"mean", sp.mean}, {"median", sp.median}}}};
    char line[400];
    std::snprintf(line, sizeof line,
                  "\nReconstructed device against the true device (3D, CT LPS, mean distance of its points per "
                  "model): %s mm over %zu models; worst point %.2f mm. It spans %.0f mm of the true device "
                  "(median; %.0f %% of its length).\n",
                  fmt(sd).c_str(), device_means.size(), device_worst, sc.median, sp.median);
    md << line;
  }
  summary["sessions"] = cases.size();
  summary["sessions_without_model"] = without_model;
}

// Per session with a model, devices/NN-<session>.mrk.json: the last model's reconstructed
// device and the true device, both in the node's CT frame, for 3D Slicer or `deform --device`.
void write_devices(const std::filesystem::path& directory, const std::vector<CaseEvaluation>& cases) {
  std::filesystem::create_directories(directory);
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const CaseEvaluation& c = cases[i];
    if (!c.model) continue;
    geometry::Markup reconstructed{"Curve", "reconstructed device", {}}, truth{"Curve", "true device", {}};
    const auto add = [](geometry::Markup& m, char prefix, const geometry::Polyline& points) {
      for (std::size_t k = 0; k < points.size(); ++k) {
        std::string label(1, prefix);
        label += std::to_string(k);
        m.points.push_back({std::move(label), points[k]});
      }
    };
    add(reconstructed, 'R', c.model->reconstruction.points);
    add(truth, 'T', c.true_device);
    char name[32];
    std::snprintf(name, sizeof name, "%02zu-", i + 1);
    geometry::write_markups(directory / (name + c.session.filename().string() + ".mrk.json"), {reconstructed, truth});
  }
}

// What the pelvis registration found, or why not; null when none was tried.
nlohmann::json pelvis_json(const std::optional<geometry::PelvisRegistration>& r) {
  if (!r) return nullptr;
  nlohmann::json views = nlohmann::json::array();
  for (const auto& v : r->views)
    views.push_back({{"view", v.name}, {"used", v.used}, {"correlation", v.correlation},
                     {"shift_px", {v.shift_px.x(), v.shift_px.y()}}, {"reason", v.reason}});
  return {{"found", r->found},
          {"shift_mm", r->found ? nlohmann::json{r->shift_mm.x(), r->shift_mm.y(), r->shift_mm.z()} : nlohmann::json()},
          {"turn_deg", r->found ? nlohmann::json(r->turn_deg()) : nlohmann::json()},
          {"rotation", r->found ? nlohmann::json{{r->rotation(0, 0), r->rotation(0, 1), r->rotation(0, 2)},
                                                 {r->rotation(1, 0), r->rotation(1, 1), r->rotation(1, 2)},
                                                 {r->rotation(2, 0), r->rotation(2, 1), r->rotation(2, 2)}}
                                : nlohmann::json()},
          {"pivot_mm", {r->pivot_mm.x(), r->pivot_mm.y(), r->pivot_mm.z()}},
          {"turned", r->turned},
          {"blocks", r->blocks},
          {"refused", r->refused},
          {"residual_px", r->residual_px},
          {"rounds", r->rounds},
          {"views", views}};
}

}  // namespace

int run_eval(const EvalCommand& cmd) {
  std::filesystem::create_directories(cmd.out);
  std::vector<CaseEvaluation> cases;
  nlohmann::json jcases = nlohmann::json::array();
  for (const auto& dir : cmd.sessions) {
    ProgressBar bar(dir.filename().string(), cmd.progress);
    EvaluationOptions options;
    options.pelvis.enabled = cmd.pelvis;
    CaseEvaluation c = evaluate_session(dir, options, [&](std::size_t done, std::size_t total) { bar.update(done, total); });
    bar.finish();
    nlohmann::json lm = nlohmann::json::array();
    for (const auto& l : c.landmarks) lm.push_back(to_json(l));
    nlohmann::json model = nullptr;
    if (c.model)
      model = {{"frames", {c.model->frame_earlier, c.model->frame_later}},
               {"separation_deg", c.model->reconstruction.separation_deg},
               {"mean_residual_px", c.model->reconstruction.mean_residual_px},
               {"device_points", c.model->reconstruction.points.size()},
               {"matched_fraction", {c.model->reconstruction.matched_fraction_1, c.model->reconstruction.matched_fraction_2}},
               {"reliable_fraction", c.model->reconstruction.reliable_fraction},
               {"kept_fraction", c.model->reconstruction.kept_fraction},
               {"reconstruct_ms", c.model->reconstruct_ms},
               {"deform_ms", c.model->deform_ms}};
    nlohmann::json devices = nlohmann::json::array();
    for (const DeviceError& e : c.devices)
      devices.push_back({{"frames", {e.frame_earlier, e.frame_later}}, {"mean_mm", e.mean_mm}, {"max_mm", e.max_mm},
                         {"covered_mm", e.covered_mm}, {"true_length_mm", e.true_length_mm}});
    jcases.push_back({{"session", dir.string()}, {"frames", c.frames}, {"candidates", c.candidates}, {"pairs", c.pairs},
                      {"adaptations", c.adaptations}, {"failures", c.failures}, {"frames_evaluated", c.frames_evaluated},
                      {"landmarks", lm}, {"model", model}, {"device_errors", devices},
                      {"device_iliac", c.device_iliac}, {"physics", c.physics}, {"difficulty", c.difficulty},
                      {"registration_residual_deg", c.registration_residual_deg}, {"pelvis", pelvis_json(c.pelvis)},
                      {"seconds", c.seconds}});
    if (!c.model) node::log().warn("{}: no adapted model ({} candidates, {} pairs{}{})", dir.string(), c.candidates, c.pairs,
                             c.failures.empty() ? "" : "; ", c.failures.empty() ? "" : c.failures.back());
    else
      node::log().info("{}: {} frames evaluated, model from frames {}+{} ({:.0f}° apart)", dir.string(), c.frames_evaluated,
                 c.model->frame_earlier, c.model->frame_later, c.model->reconstruction.separation_deg);
    cases.push_back(std::move(c));
  }
  nlohmann::json summary;
  std::ostringstream md;
  summarize(cases, summary, md);
  // Each simulated physics and difficulty on its own (docs/SYNTHETIC_PATIENTS.md): a method
  // must hold on each, not only on their mix.
  std::map<std::string, std::vector<CaseEvaluation>> groups;
  for (const auto& c : cases) groups[c.physics + " physics, " + c.difficulty + " difficulty"].push_back(c);
  if (groups.size() > 1 || (groups.size() == 1 && cases.front().physics != "unknown")) {
    for (const auto& [name, group] : groups) {
      std::ostringstream part;
      summarize(group, summary["by_physics"][name], part);
      md << "\n## " << name << "\n\n" << part.str();
    }
  }
  std::size_t without_model = 0;
  for (const auto& c : cases) without_model += c.model ? 0 : 1;
  write_json(cmd.out / "eval.json", {{"summary", summary}, {"cases", jcases}});
  write_text(cmd.out / "eval.md", "# Ostium distances, initial versus adapted\n\n" + md.str());
  write_evaluation_plots(cmd.out, cases);
  write_devices(cmd.out / "devices", cases);
  std::fputs(md.str().c_str(), stdout);
  node::log().info("wrote {} (eval.json, eval.md, per_case.png, distribution.png, snapshots/, devices/)", cmd.out.string());
  return without_model == cases.size() ? 1 : 0;
}

}  // namespace evar::app
