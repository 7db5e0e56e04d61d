// The pelvis found in the analysed frames (node/pelvis_tracker.hpp): which frames stand for a
// view of the bones, when the pelvis is registered, when the models move with it and how
// (the registration itself: tests/geometry/test_pelvis_registration.cpp; the live node and
// eval running it: tests/node/test_live_node_pelvis.cpp, tests/app/test_cli_sessions.cpp).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <numbers>

#include <opencv2/core.hpp>

#include "evar/node/pelvis_tracker.hpp"
#include "evar/sim/patient_plan.hpp"
#include "evar/sim/synthetic_patient.hpp"
#include "support/temp_dir.hpp"

namespace {

using namespace evar;

class PelvisTrackerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::TempDir();
    const auto patient = sim::make_patient(sim::PatientPlan{5, sim::Difficulty::Paper, sim::TruthPhysics::Beam, 3000, 1500});
    sim::write_patient(patient, dir_->path);
    scene_ = new geometry::Scene(geometry::load_scene(dir_->path / "scene.json"));
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete dir_;
  }
  // A 256-pixel view at LAO `primary_deg` with the table at `table_z_mm`.
  static node::FrameView view(double primary_deg, double table_z_mm = 0.0) {
    acquisition::CArmState s;
    s.primary_deg = primary_deg;
    s.sid_mm = 1200.0;
    s.sod_mm = 800.0;
    s.table_mm = {0.0, 0.0, table_z_mm};
    s.fluoro_on = true;
    geometry::DetectorSpec d;
    d.cols = d.rows = 256;
    d.row_spacing_mm = d.col_spacing_mm = 1.2;
    return node::frame_view(d, Eigen::Matrix4d::Identity(), s);
  }
  static cv::Mat blank() { return cv::Mat(256, 256, CV_16U, cv::Scalar(30000)); }

  static inline test::TempDir* dir_ = nullptr;
  static inline geometry::Scene* scene_ = nullptr;
};

// The first frame of a view stands for it: frames of the same view (within 2° and 5 mm of
// table) add nothing; another angle or the table moved is another view, and the second view
// is the time to register.
TEST_F(PelvisTrackerTest, TheFirstFrameOfEachViewIsKept) {
  ASSERT_GT(scene_->pelvis.V.rows(), 0) << "the synthetic patient has no pelvis";
  node::PelvisTracker tracker(*scene_, {}, {});
  ASSERT_TRUE(tracker.active());
  EXPECT_FALSE(tracker.offer(blank(), view(0.0), "AP"));
  EXPECT_EQ(tracker.views(), 1u);
  EXPECT_FALSE(tracker.offer(blank(), view(1.0), "AP again"));
  EXPECT_FALSE(tracker.offer(blank(), view(0.5, 3.0), "AP, table 3 mm"));
  EXPECT_EQ(tracker.views(), 1u);
  EXPECT_TRUE(tracker.offer(blank(), view(0.0, 40.0), "AP, table 40 mm"));
  EXPECT_EQ(tracker.views(), 2u);
  EXPECT_TRUE(tracker.offer(blank(), view(35.0), "LAO 35"));
  EXPECT_EQ(tracker.views(), 3u);
  // Back to the first view: it is kept already.
  EXPECT_FALSE(tracker.offer(blank(), view(0.0), "AP back"));
  EXPECT_EQ(tracker.views(), 3u);
}

// Frames that show no bones (a grey field) are not used; they are forgotten, so the view is
// tried again when the C-arm comes back to it, not at its next frame.
TEST_F(PelvisTrackerTest, ViewsTheMatchCouldNotUseAreForgottenAndTriedAgainOnReturn) {
  node::PelvisTracker tracker(*scene_, {}, {});
  ASSERT_FALSE(tracker.offer(blank(), view(0.0), "AP"));
  ASSERT_TRUE(tracker.offer(blank(), view(35.0), "LAO 35"));
  const geometry::PelvisRegistration r = tracker.register_views();
  EXPECT_FALSE(r.found);
  EXPECT_NE(r.refused.find("no view showed the pelvis"), std::string::npos) << r.refused;
  EXPECT_FALSE(tracker.moves_models(r));
  EXPECT_EQ(tracker.views(), 0u);
  EXPECT_FALSE(tracker.offer(blank(), view(35.5), "LAO 35, next frame"));  // the same visit
  EXPECT_EQ(tracker.views(), 0u);
  EXPECT_FALSE(tracker.offer(blank(), view(0.0), "AP again"));  // came back: tried again
  EXPECT_EQ(tracker.views(), 1u);
  // One view cannot fix the depth: said without calling the registration.
  const geometry::PelvisRegistration one = tracker.register_views();
  EXPECT_FALSE(one.found);
  EXPECT_NE(one.refused.find("one view"), std::string::npos) << one.refused;
}

// The models move only for a pose found, and only when it lies more than half a millimetre
// (at the bones' centroid, or 100 mm from it by the turn) from where they were last moved to.
// Moved, everything from the bifurcation down goes with the pelvis and the renal level stays.
TEST_F(PelvisTrackerTest, TheModelsMoveWithAPoseThatDiffersFromTheLastAndTheRenalLevelStays) {
  node::PelvisTracker tracker(*scene_, {}, {});
  geometry::PelvisRegistration r;
  r.found = true;
  r.pivot_mm = scene_->pelvis.V.colwise().mean().transpose();
  r.shift_mm = {0.0, 0.3, 0.3};
  EXPECT_FALSE(tracker.moves_models(r));  // 0.42 mm from the registration's pose
  r.rotation = Eigen::AngleAxisd(0.4 * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_TRUE(tracker.moves_models(r));  // 0.7 mm at 100 mm
  r.rotation.setIdentity();
  r.shift_mm = {0.0, 0.0, 8.0};
  EXPECT_TRUE(tracker.moves_models(r));
  geometry::PelvisRegistration refused = r;
  refused.found = false;
  EXPECT_FALSE(tracker.moves_models(refused));

  const auto moved = tracker.move_models(r);
  ASSERT_NE(moved, nullptr);
  ASSERT_NE(moved->deformer, nullptr);
  EXPECT_FALSE(tracker.moves_models(r));  // where the models are now
  r.shift_mm.z() += 0.4;
  EXPECT_FALSE(tracker.moves_models(r));
  r.shift_mm.z() += 0.4;
  EXPECT_TRUE(tracker.moves_models(r));
  ASSERT_EQ(moved->scene.landmarks.size(), scene_->landmarks.size());
  int internal = 0, renal = 0;
  for (std::size_t k = 0; k < scene_->landmarks.size(); ++k) {
    const Eigen::Vector3d d = moved->scene.landmarks[k].position_lps - scene_->landmarks[k].position_lps;
    const std::string& label = scene_->landmarks[k].label;
    if (label.rfind("internal_iliac", 0) == 0) {
      ++internal;
      EXPECT_LT((d - Eigen::Vector3d(0.0, 0.0, 8.0)).norm(), 1e-9) << label;
    } else if (label.rfind("renal", 0) == 0) {
      ++renal;
      // The ramp starts at the aorta's point nearest the renal ostia's mean, so an ostium a
      // few mm below it is a little way into the ramp, where the smoothstep is still flat
      // (8 mm · 3s² for s of a few hundredths).
      EXPECT_LT(d.norm(), 0.05) << label;
    }
  }
  EXPECT_EQ(internal, 2);
  EXPECT_EQ(renal, 2);
}

// Switched off, or a scene without bones: nothing is kept, nothing registered.
TEST_F(PelvisTrackerTest, DisabledOrWithoutBonesItLooksForNothing) {
  node::PelvisTrackingOptions off;
  off.enabled = false;
  node::PelvisTracker disabled(*scene_, off, {});
  EXPECT_FALSE(disabled.active());
  EXPECT_FALSE(disabled.offer(blank(), view(0.0), "AP"));
  EXPECT_FALSE(disabled.offer(blank(), view(35.0), "LAO 35"));
  EXPECT_EQ(disabled.views(), 0u);
  geometry::Scene no_bones = *scene_;
  no_bones.pelvis = {};
  node::PelvisTracker none(no_bones, {}, {});
  EXPECT_FALSE(none.active());
  EXPECT_FALSE(none.offer(blank(), view(35.0), "LAO 35"));
}

TEST_F(PelvisTrackerTest, OptionsNoTrackerRunsWithAreRefusedByName) {
  node::PelvisTrackingOptions o;
  o.max_views = 1;
  try {
    node::check_options(o);
    FAIL() << "one view accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("pelvis: max_views"), std::string::npos) << e.what();
  }
  o = {};
  o.same_view_deg = 0.0;
  EXPECT_THROW(node::check_options(o), std::invalid_argument);
  o = {};
  o.remake_mm = -1.0;
  EXPECT_THROW(node::PelvisTracker(*scene_, o, {}), std::invalid_argument);
}

}  // namespace
