// Is the picture the right way round (node/picture_orientation.hpp)? A video mapping that
// misses a mirror or a turn gives the node a device and bones turned against their
// projection; the preoperative vessels and the pelvis's bones say so, and which turn.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <vector>

#include "evar/geometry/carm_projection.hpp"
#include "evar/geometry/video_mapping.hpp"
#include "evar/node/picture_orientation.hpp"
#include "evar/node/picture_turn.hpp"
#include "evar/sim/body_phantom.hpp"
#include "evar/sim/example_scene.hpp"
#include "evar/sim/xray_render.hpp"
#include "support/carm_view.hpp"

namespace {

using namespace evar;
using node::PictureTurn;

std::vector<PictureTurn> every_turn() {
  std::vector<PictureTurn> out{{}};
  for (const auto& t : node::other_turns(true)) out.push_back(t);
  return out;
}

geometry::CArmView view(double primary_deg, double secondary_deg, int px) {
  return test::carm_view(primary_deg, secondary_deg, px, 0.6);
}

TEST(PictureTurn, PointsAndImagesTurnAlikeAndQuarterTurnsNeedASquare) {
  EXPECT_EQ(node::other_turns(true).size(), 7u);
  EXPECT_EQ(node::other_turns(false).size(), 3u);
  for (const auto& t : node::other_turns(false)) EXPECT_EQ(t.rotation_deg % 180, 0) << node::turn_text(t);
  for (const auto& [cols, rows] : {std::pair{7, 7}, std::pair{6, 4}})
    for (const PictureTurn& t : every_turn()) {
      if (cols != rows && t.rotation_deg % 180 != 0) {
        EXPECT_THROW(node::turned_points({{1.0, 2.0}}, t, cols, rows), std::invalid_argument);
        continue;
      }
      SCOPED_TRACE(node::turn_text(t) + " of " + std::to_string(cols) + " x " + std::to_string(rows));
      cv::Mat picture(rows, cols, CV_8U, cv::Scalar(0));
      picture.at<std::uint8_t>(2, 1) = 255;  // (x 1, y 2)
      const cv::Mat turned = node::turned_image(picture, t);
      cv::Point at;
      cv::minMaxLoc(turned, nullptr, nullptr, nullptr, &at);
      const Eigen::Vector2d expected = node::turned_points({{1.0, 2.0}}, t, cols, rows).front();
      EXPECT_EQ(Eigen::Vector2d(at.x, at.y), expected);
    }
  EXPECT_EQ(node::turn_text({}), "as it is");
  EXPECT_EQ(node::turn_text({0, true}), "mirrored");
  EXPECT_EQ(node::turn_text({270, true}), "turned 270 degrees clockwise and mirrored");
  for (const PictureTurn& t : every_turn())
    EXPECT_TRUE(node::turn_matrix(node::inverse(t)).isApprox(node::turn_matrix(t).inverse())) << node::turn_text(t);
}

// Whatever the display does and whatever the mapping says, one turn of what the node reads
// gives the detector's picture, and the mapping with that turn is the display's.
TEST(PictureTurn, TheMappingThatMissedATurnIsFoundFromIt) {
  geometry::VideoMapping base;
  base.video_cols = 640;
  base.video_rows = 512;
  base.image_rect = {80, 0, 512, 512};
  for (const PictureTurn& shown : every_turn())
    for (const PictureTurn& said : every_turn()) {
      geometry::VideoMapping truth = base, set = base;
      truth.rotation_deg = shown.rotation_deg;
      truth.mirror = shown.mirror;
      set.rotation_deg = said.rotation_deg;
      set.mirror = said.mirror;
      const geometry::VideoToDetector true_map(truth, 384, 384), set_map(set, 384, 384);
      const std::vector<Eigen::Vector2d> video{{100, 20}, {500, 40}, {300, 480}};
      std::vector<Eigen::Vector2d> read, real;
      for (const auto& v : video) {
        read.push_back(set_map.to_detector(v));
        real.push_back(true_map.to_detector(v));
      }
      int found = 0;
      for (const PictureTurn& missed : every_turn()) {
        const auto turned = node::turned_points(read, missed, 384, 384);
        bool same = true;
        for (std::size_t k = 0; k < video.size(); ++k) same = same && (turned[k] - real[k]).norm() < 1e-6;
        if (!same) continue;
        ++found;
        const auto fixed = node::mapping_with_turn(set, missed, 384, 384);
        ASSERT_TRUE(fixed);
        EXPECT_EQ(fixed->rotation_deg, shown.rotation_deg);
        EXPECT_EQ(fixed->mirror, shown.mirror);
        EXPECT_EQ(missed == PictureTurn{}, shown == said);
        // On screen the roadmap is drawn turned against the picture by L_set · L_true⁻¹.
        const Eigen::Matrix2d on_screen = node::turn_matrix({said.rotation_deg, said.mirror}) *
                                          node::turn_matrix({shown.rotation_deg, shown.mirror}).transpose();
        EXPECT_LT((node::turn_matrix(node::turn_as_shown(missed, set)) - on_screen).cwiseAbs().maxCoeff(), 1e-12);
      }
      EXPECT_EQ(found, 1) << node::turn_text(shown) << " said " << node::turn_text(said);
    }
  // A quarter turn of a picture that is not square is no mapping's.
  base.image_rect = {80, 0, 480, 360};
  EXPECT_FALSE(node::mapping_with_turn(base, {90, false}, 400, 300));
  const auto upside_down = node::mapping_with_turn(base, {180, false}, 400, 300);
  ASSERT_TRUE(upside_down);
  EXPECT_EQ(upside_down->rotation_deg, 180);
  EXPECT_FALSE(upside_down->mirror);
  // The live node's case: a display that turns by 270° and mirrors, a mapping without the
  // mirror: the node reads the detector's picture upside down, and the screen shows the
  // roadmap left for right.
  base.rotation_deg = 270;
  EXPECT_EQ(node::turn_as_shown({180, true}, base), (PictureTurn{0, true}));
}

TEST(TurnStreak, SaysTheTurnsTwoChecksInARowShare) {
  node::TurnStreak streak;
  using Turns = std::vector<PictureTurn>;
  const PictureTurn mirror{0, true}, upside{180, false}, quarter{90, false};
  EXPECT_EQ(streak.suspect({upside, mirror}), Turns{});       // one check is not enough
  EXPECT_EQ(streak.suspect({mirror}), Turns{mirror});         // the next singles out the one they share
  EXPECT_EQ(streak.suspect({mirror, quarter}), Turns{mirror});
  EXPECT_EQ(streak.length(), 3);
  EXPECT_EQ(streak.suspect({quarter}), Turns{});  // another turn starts over
  EXPECT_EQ(streak.length(), 1);
  streak.confirm();  // a view read right as taken
  EXPECT_EQ(streak.suspect({quarter, upside}), Turns{});
  EXPECT_EQ(streak.suspect({upside, quarter}), (Turns{upside, quarter}));  // both, the latest's best first
  EXPECT_THROW(streak.suspect({}), std::invalid_argument);
}

std::vector<Eigen::Vector2d> projected(const geometry::ProjectionMatrix& P, const geometry::Polyline& curve) {
  std::vector<Eigen::Vector2d> out;
  for (const auto& X : geometry::resample(curve, 0.5)) out.push_back(*geometry::project(P, X));
  return out;
}

node::ViewCandidate candidate(const geometry::CArmView& v, const geometry::Polyline& device, const PictureTurn& turn) {
  node::ViewCandidate c;
  c.geometry.view = v;
  c.geometry.P_ct = geometry::projection_matrix(v);
  c.curve_px = node::turned_points(projected(c.geometry.P_ct, device), turn, v.detector_cols, v.detector_rows);
  return c;
}

// The device seen in AP and in an angled view of the bifurcation, its pictures turned
// against their projections: the device so read misses the vessels by centimetres, and
// reads into them only turned back. (A mirror, or a turn upside down, the example's
// symmetric vessels centred on the isocenter take in: the other iliac, the aorta hold the
// wire so read, 2-4 mm outside. The bones tell those, below; on the simulator's sessions,
// whose table lies off the midline, the device does too.)
TEST(PictureOrientation, ADeviceReadTurnedLiesInTheVesselsOnlyTurnedBack) {
  const auto example = sim::make_example_scene({});
  const auto scene = sim::to_scene(example);
  const deform::SceneDeformer deformer(scene);
  const node::AdaptationOptions options;
  const auto ap = view(0.0, 0.0, 1024), oblique = view(-25.0, -15.0, 1024);
  {
    const node::ViewPair pair{candidate(ap, example.device, {}), candidate(oblique, example.device, {}), 29.0};
    const auto c = node::check_picture_orientation(deformer, pair, options);
    EXPECT_TRUE(c.confirmed);
    EXPECT_LT(c.as_set.outside_mm, options.reading_margin_mm);
    EXPECT_TRUE(c.tried.empty()) << "a device in the vessels as taken needs no other turn tried";
    EXPECT_FALSE(c.better);
  }
  for (const PictureTurn& shown : {PictureTurn{90, false}, PictureTurn{270, false}, PictureTurn{90, true}}) {
    SCOPED_TRACE(node::turn_text(shown));
    // The node reads the turned picture as if it were not: the turn back is what it missed.
    const node::ViewPair pair{candidate(ap, example.device, shown), candidate(oblique, example.device, shown), 29.0};
    const auto c = node::check_picture_orientation(deformer, pair, options);
    EXPECT_FALSE(c.confirmed);
    EXPECT_GT(c.as_set.outside_mm, options.orientation_outside_mm);
    ASSERT_TRUE(c.better) << c.as_set.outside_mm;
    // Turning back: a quarter turn clockwise is undone by three more.
    const PictureTurn back{shown.mirror ? shown.rotation_deg : (360 - shown.rotation_deg) % 360, shown.mirror};
    EXPECT_EQ(c.better->turn, back) << node::turn_text(c.better->turn);
    EXPECT_LT(c.better->outside_mm, options.reading_margin_mm);
    EXPECT_EQ(c.candidates.front(), back);
    EXPECT_EQ(node::shown_turn(back, nullptr), shown);
    EXPECT_NE(c.problem.find("only if the picture is shown " + node::turn_text(shown)), std::string::npos) << c.problem;
  }
}

// The pelvis's bones in a noisy frame of the body phantom (its bones analytic, the CT's a
// mesh of them): an oblique view matches them only the right way round; an AP view of the
// symmetric pelvis matches mirrored as well and confirms nothing.
TEST(PictureOrientation, AnObliqueViewsBonesMatchOnlyTheRightWayRound) {
  const sim::BodyPhantom body = sim::default_body_phantom();
  const geometry::RayCaster bones(sim::pelvis_mesh(body));
  Eigen::Matrix4d ct_to_carm = Eigen::Matrix4d::Identity();
  ct_to_carm.topRightCorner<3, 1>() = -Eigen::Vector3d(0.0, 30.0, -60.0);
  const auto frame = [&](const geometry::CArmView& v) {
    sim::XRayContent content;
    content.body = &body;
    content.patient_to_world = ct_to_carm;
    return sim::detect(sim::expected_xray(v, content).quanta, {}, 7);
  };
  for (const auto& [primary, secondary] : {std::pair{35.0, 0.0}, std::pair{-25.0, -15.0}}) {
    const auto v = view(primary, secondary, 512);
    const geometry::ProjectionMatrix P = geometry::registered(geometry::projection_matrix(v), ct_to_carm);
    const cv::Mat taken = frame(v);
    SCOPED_TRACE("primary " + std::to_string(primary));
    const auto right = node::check_bone_orientation(bones, {P, taken, "right"}, {});
    EXPECT_TRUE(right.as_set.used) << right.as_set.reason;
    EXPECT_TRUE(right.confirmed);
    EXPECT_FALSE(right.better);
    EXPECT_EQ(right.tried.size(), 7u);
    const auto mirrored = node::check_bone_orientation(bones, {P, node::turned_image(taken, {0, true}), "mirrored"}, {});
    EXPECT_FALSE(mirrored.confirmed);
    ASSERT_TRUE(mirrored.better) << mirrored.as_set.correlation;
    EXPECT_EQ(mirrored.better->first, (PictureTurn{0, true}));
    EXPECT_NE(mirrored.problem.find("only if the picture is shown mirrored"), std::string::npos) << mirrored.problem;
    EXPECT_NE(mirrored.problem.find("roadmap drawn left for right"), std::string::npos) << mirrored.problem;
  }
  const auto ap = view(0.0, 0.0, 512);
  const geometry::ProjectionMatrix P = geometry::registered(geometry::projection_matrix(ap), ct_to_carm);
  const auto symmetric = node::check_bone_orientation(bones, {P, node::turned_image(frame(ap), {0, true}), "AP"}, {});
  EXPECT_TRUE(symmetric.as_set.used);
  EXPECT_FALSE(symmetric.confirmed) << "an AP view of a symmetric pelvis cannot tell a mirror";
  EXPECT_FALSE(symmetric.better);
}

}  // namespace
