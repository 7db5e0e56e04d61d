#include "evaluation_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "evaluation_charts.hpp"
#include "evar/node/frame_view.hpp"
#include "evar/node/model_adaptation.hpp"
#include "evar/overlay/frame_compositor.hpp"
#include "evar/session/session.hpp"
#include "evar/session/session_replay.hpp"

namespace evar::app {

namespace {

void snapshot(const std::filesystem::path& path, const CaseEvaluation& c) {
  const session::Session& session = *c.recording;
  const auto model = std::make_shared<const overlay::RoadmapModel>(node::roadmap_model(*c.scene, c.model.get()));
  const session::FrameRecord& record = session.frames[c.snapshot_frame];
  const session::CArmSample* sample = session::carm_at(session, record.timestamp_ns);
  const node::FrameView view =
      node::frame_view(session::view_of(session, *sample), session.ct_to_carm, session::to_carm_state(*sample, 0));
  const cv::Mat image = session::read_detector_frame(session, c.snapshot_frame);
  overlay::FrameCompositor compositor({4, {}});
  const std::string line =
      "frame " + std::to_string(record.frame) + "  " + node::angulation_text(sample->primary_deg, sample->secondary_deg);
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
  write_per_case_chart(directory / "per_case.png", cases);
  write_distribution_chart(directory / "distribution.png", cases);
  std::filesystem::create_directories(directory / "snapshots");
  for (std::size_t i = 0; i < cases.size(); ++i)
    if (cases[i].model) {
      char name[32];
      std::snprintf(name, sizeof name, "%02zu-", i + 1);
      snapshot(directory / "snapshots" / (name + cases[i].session.filename().string() + ".png"), cases[i]);
    }
}

}  // namespace evar::app
