#include "evaluation_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "evar/overlay/frame_compositor.hpp"
#include "evar/sim/session.hpp"
#include "evar/sim/session_replay.hpp"
#include "frame_view.hpp"
#include "model_adaptation.hpp"

namespace evar::app {

namespace {

const cv::Scalar kBackground(255, 255, 255), kAxis(60, 60, 60), kGrid(225, 225, 225);
const cv::Scalar kInitialColour(170, 150, 120), kAdaptedColour(40, 140, 250);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

void write_png(const std::filesystem::path& path, const cv::Mat& image) {
  if (!cv::imwrite(path.string(), image)) throw std::runtime_error(path.string() + ": cannot write");
}

void text(cv::Mat& m, const std::string& s, cv::Point at, double scale = 0.45, cv::Scalar c = kAxis) {
  cv::putText(m, s, at, kFont, scale, c, 1, cv::LINE_AA);
}

// A nice tick step (1, 2 or 5 times a power of ten) giving about 5 ticks up to `top`.
double tick_step(double top) {
  const double raw = std::max(top, 1e-6) / 5.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10.0 * p;
}

struct Axes {
  cv::Rect plot;
  double top;  // mm at the top of the plot
  int y(double mm) const { return plot.y + plot.height - static_cast<int>(std::lround(mm / top * plot.height)); }
};

Axes draw_axes(cv::Mat& m, const std::string& title, const std::string& y_label, double max_value) {
  Axes a{{70, 50, m.cols - 100, m.rows - 110}, 0};
  const double step = tick_step(max_value * 1.1);
  a.top = step * std::ceil(max_value * 1.1 / step);
  if (a.top <= 0) a.top = 1;
  text(m, title, {a.plot.x, 30}, 0.6);
  for (double v = 0; v <= a.top + 1e-9; v += step) {
    const int y = a.y(v);
    cv::line(m, {a.plot.x, y}, {a.plot.x + a.plot.width, y}, kGrid, 1);
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    text(m, b, {a.plot.x - 45, y + 5});
  }
  cv::line(m, {a.plot.x, a.plot.y}, {a.plot.x, a.plot.y + a.plot.height}, kAxis, 1);
  cv::line(m, {a.plot.x, a.plot.y + a.plot.height}, {a.plot.x + a.plot.width, a.plot.y + a.plot.height}, kAxis, 1);
  text(m, y_label, {8, a.plot.y - 12});
  return a;
}

void legend(cv::Mat& m, cv::Point at) {
  cv::rectangle(m, cv::Rect(at.x, at.y - 10, 14, 10), kInitialColour, cv::FILLED);
  text(m, "initial (preoperative)", {at.x + 20, at.y});
  cv::rectangle(m, cv::Rect(at.x + 200, at.y - 10, 14, 10), kAdaptedColour, cv::FILLED);
  text(m, "adapted", {at.x + 220, at.y});
}

double case_mean(const CaseEvaluation& c, bool adapted) {
  if (c.landmarks.empty()) return 0.0;
  double s = 0;
  for (const auto& l : c.landmarks) s += adapted ? l.adapted_mm : l.initial_mm;
  return s / static_cast<double>(c.landmarks.size());
}

void per_case(const std::filesystem::path& path, const std::vector<CaseEvaluation>& cases) {
  const int n = static_cast<int>(cases.size());
  cv::Mat m(420, std::max(480, 110 + 34 * n), CV_8UC3, kBackground);
  double top = 0;
  for (const auto& c : cases) top = std::max({top, case_mean(c, false), case_mean(c, true)});
  const Axes a = draw_axes(m, "Mean ostium distance per session (2D, mm at the isocenter)", "mm", top);
  const double slot = static_cast<double>(a.plot.width) / std::max(n, 1);
  for (int i = 0; i < n; ++i) {
    const int x0 = a.plot.x + static_cast<int>(i * slot + 0.15 * slot);
    const int w = std::max(2, static_cast<int>(0.35 * slot));
    const int base = a.plot.y + a.plot.height;
    if (!cases[i].model) {
      text(m, "-", {x0 + w / 2, base - 6});
    } else {
      cv::rectangle(m, cv::Point(x0, a.y(case_mean(cases[i], false))), cv::Point(x0 + w, base), kInitialColour, cv::FILLED);
      cv::rectangle(m, cv::Point(x0 + w, a.y(case_mean(cases[i], true))), cv::Point(x0 + 2 * w, base), kAdaptedColour,
                    cv::FILLED);
    }
    text(m, std::to_string(i + 1), {x0 + w / 2, base + 18}, 0.4);
  }
  text(m, "session", {a.plot.x + a.plot.width / 2 - 25, a.plot.y + a.plot.height + 38});
  legend(m, {a.plot.x, m.rows - 12});
  write_png(path, m);
}

void histogram(const std::filesystem::path& path, const std::vector<CaseEvaluation>& cases) {
  const std::vector<double> initial = landmark_values(cases, &LandmarkError::initial_mm),
                            adapted = landmark_values(cases, &LandmarkError::adapted_mm);
  double hi = 1.0;
  for (double v : initial) hi = std::max(hi, v);
  for (double v : adapted) hi = std::max(hi, v);
  const double width = tick_step(hi) / 2.0;
  const int bins = static_cast<int>(std::ceil(hi / width + 1e-9));
  std::vector<int> ci(bins, 0), ca(bins, 0);
  for (double v : initial) ++ci[std::min(bins - 1, static_cast<int>(v / width))];
  for (double v : adapted) ++ca[std::min(bins - 1, static_cast<int>(v / width))];
  const int most = std::max(*std::max_element(ci.begin(), ci.end()), *std::max_element(ca.begin(), ca.end()));
  cv::Mat m(420, 640, CV_8UC3, kBackground);
  const Axes a = draw_axes(m, "Ostium distances, all landmarks and sessions", "count", most);
  const double slot = static_cast<double>(a.plot.width) / bins;
  const int base = a.plot.y + a.plot.height;
  for (int b = 0; b < bins; ++b) {
    const int x0 = a.plot.x + static_cast<int>(b * slot);
    const int w = std::max(1, static_cast<int>(slot / 2) - 1);
    if (ci[b]) cv::rectangle(m, cv::Point(x0 + 1, a.y(ci[b])), cv::Point(x0 + w, base), kInitialColour, cv::FILLED);
    if (ca[b]) cv::rectangle(m, cv::Point(x0 + w + 1, a.y(ca[b])), cv::Point(x0 + 2 * w, base), kAdaptedColour, cv::FILLED);
  }
  const int label_every = std::max(1, bins / 10);
  for (int b = 0; b <= bins; b += label_every) {
    char s[32];
    std::snprintf(s, sizeof s, "%g", b * width);
    text(m, s, {a.plot.x + static_cast<int>(b * slot) - 8, base + 18}, 0.4);
  }
  text(m, "mm at the isocenter", {a.plot.x + a.plot.width / 2 - 70, base + 38});
  legend(m, {a.plot.x, m.rows - 12});
  write_png(path, m);
}

void snapshot(const std::filesystem::path& path, const CaseEvaluation& c) {
  const sim::Session& session = *c.recording;
  const auto model = std::make_shared<const overlay::RoadmapModel>(roadmap_model(*c.scene, c.model.get()));
  const sim::FrameRecord& record = session.frames[c.snapshot_frame];
  const sim::CArmSample* sample = sim::carm_at(session, record.timestamp_ns);
  const FrameView view = frame_view(session.detector, session.ct_to_carm, sim::to_carm_state(*sample, 0));
  const cv::Mat image = sim::read_session_frame(session, c.snapshot_frame);
  overlay::FrameCompositor compositor({4, {}});
  const std::string line =
      "frame " + std::to_string(record.frame) + "  " + angulation_text(sample->primary_deg, sample->secondary_deg);
  overlay::Image out =
      compositor.compose({image.cols, image.rows, static_cast<int>(image.step), 16, image.data}, &view.P_ct, model,
                         overlay::RoadmapMode::Both,
                         {{line, "blue: preoperative  orange: adapted  white +: true ostia"}, {}});
  cv::Mat m(out.height, out.width, CV_8UC3, out.bgr.data());
  for (const auto& o : session.truth->ostia)
    if (o.frame == record.frame)
      cv::drawMarker(m, cv::Point(static_cast<int>(std::lround(o.pixel.x())), static_cast<int>(std::lround(o.pixel.y()))),
                     cv::Scalar(255, 255, 255), cv::MARKER_CROSS, 12, 1, cv::LINE_AA);
  overlay::write_png(path, out);
}

}  // namespace

void write_evaluation_plots(const std::filesystem::path& directory, const std::vector<CaseEvaluation>& cases) {
  per_case(directory / "per_case.png", cases);
  histogram(directory / "histogram.png", cases);
  std::filesystem::create_directories(directory / "snapshots");
  for (std::size_t i = 0; i < cases.size(); ++i)
    if (cases[i].model) {
      char name[32];
      std::snprintf(name, sizeof name, "%02zu-", i + 1);
      snapshot(directory / "snapshots" / (name + cases[i].session.filename().string() + ".png"), cases[i]);
    }
}

}  // namespace evar::app
