#include "evar/geometry/pelvis_registration.hpp"

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <optional>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "evar/base/quantity_text.hpp"

namespace evar::geometry {
namespace {

// Gradients of a smoothed image: the part of an X-ray picture that bones decide.
void smoothed_gradients(const cv::Mat& image, cv::Mat g[2]) {
  cv::Mat smooth;
  cv::GaussianBlur(image, smooth, cv::Size(0, 0), 1.0);
  cv::Sobel(smooth, g[0], CV_32F, 1, 0, 3);
  cv::Sobel(smooth, g[1], CV_32F, 0, 1, 3);
}

// −log of the frame's grey level, at the matched images' size: the line integral of the
// attenuation up to a constant, where bone adds its thickness times its density.
// Each matched pixel stands for a step x step block of the detector (the bones' image samples
// its centre), so the frame is padded to whole blocks before it is averaged down. Grey levels
// are floored a millionth of the brightest above zero (a frame of any depth or scale).
cv::Mat attenuation_image(const cv::Mat& frame, cv::Size size, int step) {
  cv::Mat grey;
  frame.convertTo(grey, CV_32F);
  cv::copyMakeBorder(grey, grey, 0, std::max(0, size.height * step - grey.rows), 0, std::max(0, size.width * step - grey.cols),
                     cv::BORDER_REPLICATE);
  cv::Mat small;
  cv::resize(grey, small, size, 0, 0, cv::INTER_AREA);
  double brightest = 0.0;
  cv::minMaxLoc(small, nullptr, &brightest);
  cv::max(small, std::max(brightest * 1e-6, 1e-30), small);
  cv::log(small, small);
  return -small;
}

// The peak of a correlation map to a fraction of a pixel: a parabola through it and its
// neighbours, per axis. `at` must not lie on the map's border.
Eigen::Vector2d subpixel_peak(const cv::Mat& r, cv::Point at) {
  const auto vertex = [](float a, float b, float c) {
    const double d = a - 2.0 * b + c;
    return d < 0.0 ? std::clamp(0.5 * (a - c) / d, -0.5, 0.5) : 0.0;
  };
  return {at.x + vertex(r.at<float>(at.y, at.x - 1), r.at<float>(at.y, at.x), r.at<float>(at.y, at.x + 1)),
          at.y + vertex(r.at<float>(at.y - 1, at.x), r.at<float>(at.y, at.x), r.at<float>(at.y + 1, at.x))};
}

// Gradient correlation of `templ` of the bones' gradients over `search` of the frame's: the
// mean of the two directions' normalized cross-correlations, one value per placement.
cv::Mat gradient_correlation(const cv::Mat f[2], const cv::Mat b[2], const cv::Rect& search, const cv::Rect& templ) {
  cv::Mat rx, ry;
  cv::matchTemplate(f[0](search), b[0](templ), rx, cv::TM_CCOEFF_NORMED);
  cv::matchTemplate(f[1](search), b[1](templ), ry, cv::TM_CCOEFF_NORMED);
  return 0.5 * (rx + ry);
}

struct ViewMatch {
  bool ok = false;
  double correlation = 0.0;
  Eigen::Vector2d shift_cells{0, 0};
  std::string reason;
};

// The shift (matched-image pixels) that best lays the bones' gradients `b` over the frame's
// `f`, searched over ±reach pixels.
ViewMatch match_bones(const cv::Mat f[2], const cv::Mat b[2], const cv::Mat& bone, int reach, const PelvisRegistrationOptions& options) {
  ViewMatch m;
  const cv::Rect image(0, 0, bone.cols, bone.rows);
  const cv::Rect inner(reach, reach, bone.cols - 2 * reach, bone.rows - 2 * reach);
  if (inner.width < 8 || inner.height < 8) {
    m.reason = "the searched range is as large as the image";
    return m;
  }
  const cv::Mat mask = bone > 0.5f;
  const cv::Rect bones_box = cv::boundingRect(mask);
  const cv::Rect templ = (bones_box + cv::Size(4, 4) - cv::Point(2, 2)) & inner;
  if (templ.area() < 64 || cv::countNonZero(mask(templ)) < options.min_bone_fraction * templ.area()) {
    m.reason = "too little of the pelvis in the field";
    return m;
  }
  const cv::Rect search = (templ + cv::Size(2 * reach, 2 * reach) - cv::Point(reach, reach)) & image;
  const cv::Mat r = gradient_correlation(f, b, search, templ);
  double best = 0.0;
  cv::Point at;
  cv::minMaxLoc(r, nullptr, &best, nullptr, &at);
  m.correlation = best;
  if (at.x == 0 || at.y == 0 || at.x == r.cols - 1 || at.y == r.rows - 1) {
    m.reason = "the best match lies at the end of the searched range";
    return m;
  }
  m.shift_cells = subpixel_peak(r, at) - Eigen::Vector2d(templ.x - search.x, templ.y - search.y);
  if (best < options.min_correlation) {
    m.reason = "the bones match the frame with a gradient correlation of only " + base::quantity_text(best, "", 2) +
               " (needs " + base::quantity_text(options.min_correlation, "", 2) + ")";
    return m;
  }
  m.ok = true;
  return m;
}

// d(pixel)/d(X) of P at X: the 2x3 Jacobian of the projection.
Eigen::Matrix<double, 2, 3> projection_jacobian(const ProjectionMatrix& P, const Eigen::Vector3d& X) {
  const Eigen::Vector3d h = P.leftCols<3>() * X + P.col(3);
  const double u = h.x() / h.z(), v = h.y() / h.z();
  Eigen::Matrix<double, 2, 3> J;
  J.row(0) = (P.row(0).head<3>() - u * P.row(2).head<3>()) / h.z();
  J.row(1) = (P.row(1).head<3>() - v * P.row(2).head<3>()) / h.z();
  return J;
}

}  // namespace

cv::Mat bone_thickness_image(const RayCaster& bones, const ProjectionMatrix& P, int cols, int rows, int step_px,
                             cv::Mat* mean_depth_mm) {
  if (step_px < 1 || cols < 1 || rows < 1) throw std::invalid_argument("bone_thickness_image: sizes and step must be positive");
  const PinholeCamera camera = pinhole_camera(P);
  const TriangleMesh& mesh = bones.mesh();
  const int w = (cols + step_px - 1) / step_px, h = (rows + step_px - 1) / step_px;
  cv::Mat out(h, w, CV_32F, cv::Scalar(0.0f));
  const double centre = 0.5 * (step_px - 1);
  cv::Mat valid(h, w, CV_8U, cv::Scalar(1));
  cv::Mat depth(h, w, CV_32F, cv::Scalar(0.0f));
  for (int i = 0; i < h; ++i)
    for (int j = 0; j < w; ++j) {
      const Eigen::Vector3d d = back_projected_ray(camera, {j * step_px + centre, i * step_px + centre});
      // Σ over crossings of ±t (leaving a surface +t, entering −t): the chords inside.
      // Embree works in single precision: 800 mm from the source a crossing is found again
      // unless the next search starts clear of it (0.01 mm; bone surfaces lie further apart),
      // and a ray through an edge or a vertex may report it once per face there: a
      // crossing the same way within 0.05 mm of the last is that one again.
      double sum = 0.0, moment = 0.0, t_min = 0.0, last_t = -1.0;
      int inside = 0, last_side = 0;
      for (int k = 0; k < 64; ++k) {
        const auto hit = bones.first_hit(camera.source_mm, d, std::numeric_limits<double>::infinity(), t_min);
        if (!hit) break;
        t_min = hit->t_mm + 0.01;
        const Eigen::Vector3d a = mesh.V.row(mesh.F(hit->face, 0)), b = mesh.V.row(mesh.F(hit->face, 1)),
                              c = mesh.V.row(mesh.F(hit->face, 2));
        const int side = (b - a).cross(c - a).dot(d) > 0.0 ? 1 : -1;  // +1 leaving, −1 entering
        if (side == last_side && hit->t_mm - last_t < 0.05) continue;
        last_side = side, last_t = hit->t_mm;
        inside -= side;
        sum += side * hit->t_mm;
        moment += side * 0.5 * hit->t_mm * hit->t_mm;  // Σ ∫ t dt over the chords
      }
      // A crossing missed (a ray through a crack) leaves the ray inside or beyond outside:
      // that pixel is filled from its neighbours instead.
      if (inside != 0 || sum < 0.0) valid.at<std::uint8_t>(i, j) = 0;
      else {
        out.at<float>(i, j) = static_cast<float>(sum);
        if (sum > 1e-6) depth.at<float>(i, j) = static_cast<float>(moment / sum);
      }
    }
  if (static_cast<std::size_t>(cv::countNonZero(valid)) < valid.total()) {
    cv::Mat sum_near, count_near;
    cv::boxFilter(out, sum_near, CV_32F, cv::Size(3, 3), cv::Point(-1, -1), false);
    cv::boxFilter(valid, count_near, CV_32F, cv::Size(3, 3), cv::Point(-1, -1), false);
    for (int i = 0; i < h; ++i)
      for (int j = 0; j < w; ++j)
        if (valid.at<std::uint8_t>(i, j) == 0)
          out.at<float>(i, j) = count_near.at<float>(i, j) > 0.0f ? sum_near.at<float>(i, j) / count_near.at<float>(i, j) : 0.0f;
  }
  if (mean_depth_mm != nullptr) *mean_depth_mm = depth;
  return out;
}

double PelvisRegistration::turn_deg() const { return Eigen::AngleAxisd(rotation).angle() * 180.0 / std::numbers::pi; }

void check_options(const PelvisRegistrationOptions& options) {
  if (options.step_px < 1 || options.blocks_across < 1 || options.max_rounds < 1 || options.min_blocks < 0 ||
      !(options.max_shift_mm > 0.0 && options.max_shift_mm <= 500.0) || !(options.max_turn_deg > 0.0) || !(options.settled_mm > 0.0) ||
      !std::isfinite(options.min_correlation) || !std::isfinite(options.min_separation_deg) ||
      !std::isfinite(options.min_bone_fraction) || !(options.truncate_below >= 0.0 && options.truncate_below < 1.0))
    throw std::invalid_argument("register_pelvis: implausible options (a step of at least 1 px, blocks no smaller, "
                                "at least one round, a searched distance over 0 and up to 500 mm, a turn limit over 0, "
                                "a settled step over 0, a truncation share from 0 to under 1)");
}

namespace {

// One view's frame against the bones seen through P_render: the images matched (the bones'
// thickness, with its depth when asked, and both gradients) and the whole view's best
// shift, searched over max_shift_mm at the bones around `at_mm` as P sees them there (J).
struct ViewImages {
  Eigen::Matrix<double, 2, 3> J = Eigen::Matrix<double, 2, 3>::Zero();
  cv::Mat bone, depth, f[2], g[2];
  ViewMatch match;
};

ViewImages match_view(const RayCaster& caster, const ProjectionMatrix& P, const ProjectionMatrix& P_render,
                      const Eigen::Vector3d& at_mm, const cv::Mat& frame, const PelvisRegistrationOptions& options,
                      bool with_depth) {
  ViewImages v;
  if (frame.empty() || frame.channels() != 1) {
    v.match.reason = "not a one-channel image";
    return v;
  }
  v.J = projection_jacobian(P, at_mm);
  // How many matched pixels the searched distance is, at the bones.
  const double px_per_mm = v.J.norm() / std::sqrt(2.0);
  const int reach = std::max(2, static_cast<int>(std::ceil(options.max_shift_mm * px_per_mm / options.step_px)));
  v.bone = bone_thickness_image(caster, P_render, frame.cols, frame.rows, options.step_px, with_depth ? &v.depth : nullptr);
  smoothed_gradients(attenuation_image(frame, v.bone.size(), options.step_px), v.f);
  smoothed_gradients(v.bone, v.g);
  v.match = match_bones(v.f, v.g, v.bone, reach, options);
  return v;
}

}  // namespace

PelvisViewMatch match_pelvis_view(const RayCaster& bones, const PelvisView& view, const PelvisRegistrationOptions& options) {
  check_options(options);
  const Eigen::Vector3d centroid = bones.mesh().V.colwise().mean().transpose();
  const ViewMatch m = match_view(bones, view.P_ct, view.P_ct, centroid, view.frame, options, false).match;
  return {view.name, m.ok, m.correlation, m.shift_cells * options.step_px, m.reason};
}

PelvisRegistration register_pelvis(const TriangleMesh& bones_ct, const std::vector<PelvisView>& views,
                                   const PelvisRegistrationOptions& options) {
  if (bones_ct.V.rows() == 0 || bones_ct.F.rows() == 0) throw std::invalid_argument("register_pelvis: no bones");
  check_options(options);
  if (views.empty()) throw std::invalid_argument("register_pelvis: no views");
  const RayCaster caster(bones_ct);
  PelvisRegistration out;
  out.pivot_mm = bones_ct.V.colwise().mean().transpose();
  const double extent_mm = (bones_ct.V.rowwise() - out.pivot_mm.transpose()).rowwise().norm().maxCoeff();
  out.views.resize(views.size());
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  bool translation_settled = false;
  // The turning rounds' steps (turn as its motion 50 mm out, then translation, mm): a step
  // against the last one's direction means the rounds swing about the pose (noisy block
  // matches overshoot), and every later step is halved once more.
  Eigen::Matrix<double, 6, 1> last_turning_step = Eigen::Matrix<double, 6, 1>::Zero();
  double damping = 1.0;
  for (int round = 0; round < options.max_rounds; ++round) {
    // The bones where the pose so far puts them: x ↦ R(x − c) + c + t.
    Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
    pose.topLeftCorner<3, 3>() = R;
    pose.topRightCorner<3, 1>() = out.pivot_mm + t - R * out.pivot_mm;
    const Eigen::Vector3d c = out.pivot_mm + t;
    Eigen::MatrixXd A_t(0, 3), A_6(0, 6);  // the whole views' shifts (translation); the blocks' (turn and translation)
    Eigen::VectorXd b_t(0), b_6(0);
    std::vector<Eigen::Vector3d> rays;
    std::vector<int> blocks_per_view;
    double sum_sq = 0.0;
    int used = 0;
    for (std::size_t k = 0; k < views.size(); ++k) {
      const PelvisView& view = views[k];
      PelvisViewMatch& report = out.views[k];
      report = {view.name, false, 0.0, {0, 0}, ""};
      const ProjectionMatrix P_moved = view.P_ct * pose;
      const ViewImages images = match_view(caster, view.P_ct, P_moved, c, view.frame, options, true);
      const auto& [J, bone, depth, f, g, m] = images;
      report.correlation = m.correlation;
      report.shift_px = m.shift_cells * options.step_px;
      if (!m.ok) {
        report.reason = m.reason;
        continue;
      }
      report.used = true;
      ++used;
      A_t.conservativeResize(A_t.rows() + 2, 3);
      b_t.conservativeResize(b_t.rows() + 2);
      A_t.bottomRows<2>() = J;
      b_t.tail<2>() = report.shift_px;
      sum_sq += report.shift_px.squaredNorm();
      rays.push_back((c - pinhole_camera(view.P_ct).source_mm).normalized());

      // Blocks: each matched on its own, a little around the whole view's shift.
      int matched = 0;
      const int block = std::max(4, view.frame.cols / options.blocks_across / options.step_px);
      const PinholeCamera moved_camera = pinhole_camera(P_moved);  // the bone mesh as it is, seen as moved
      const cv::Point whole(static_cast<int>(std::lround(m.shift_cells.x())), static_cast<int>(std::lround(m.shift_cells.y())));
      const int local = 3;
      const cv::Rect image(0, 0, bone.cols, bone.rows);
      for (int y0 = 0; y0 + block <= bone.rows; y0 += block / 2)
        for (int x0 = 0; x0 + block <= bone.cols; x0 += block / 2) {
          const cv::Rect cell(x0, y0, block, block);
          const cv::Rect search = (cell + whole + cv::Size(2 * local, 2 * local) - cv::Point(local, local));
          if ((search & image) != search) continue;
          const cv::Mat thick = bone(cell);
          if (cv::countNonZero(thick > 0.5f) < 0.25 * cell.area()) continue;
          const cv::Mat r = gradient_correlation(f, g, search, cell);
          double best = 0.0;
          cv::Point at;
          cv::minMaxLoc(r, nullptr, &best, nullptr, &at);
          if (best < options.min_correlation || at.x == 0 || at.y == 0 || at.x == r.cols - 1 || at.y == r.rows - 1) continue;
          const Eigen::Vector2d shift_px =
              options.step_px * (subpixel_peak(r, at) + Eigen::Vector2d(whole.x - local, whole.y - local));
          // The bone the block shows: its rays' thickness-weighted points, on the bone mesh
          // (P_moved projects the mesh as the pose moves it), then where the pose puts them.
          Eigen::Vector3d X = Eigen::Vector3d::Zero();
          double weight = 0.0;
          const double centre = 0.5 * (options.step_px - 1);
          for (int i = y0; i < y0 + block; ++i)
            for (int j = x0; j < x0 + block; ++j) {
              const float w = thick.at<float>(i - y0, j - x0);
              if (w <= 0.5f || depth.at<float>(i, j) <= 0.0f) continue;  // no bone, or a ray filled in from its neighbours
              X += w * (moved_camera.source_mm +
                        depth.at<float>(i, j) * back_projected_ray(moved_camera, {j * options.step_px + centre, i * options.step_px + centre}));
              weight += w;
            }
          if (weight <= 0.0) continue;
          X /= weight;
          const Eigen::Vector3d at_pose = (pose * X.homogeneous()).head<3>();
          const Eigen::Matrix<double, 2, 3> Jp = projection_jacobian(view.P_ct, at_pose);
          // δx = δθ × (x − c) + δt:  J·(−[x − c]× δθ + δt).
          Eigen::Matrix3d cross;
          const Eigen::Vector3d r_c = at_pose - c;
          cross << 0, -r_c.z(), r_c.y(), r_c.z(), 0, -r_c.x(), -r_c.y(), r_c.x(), 0;
          A_6.conservativeResize(A_6.rows() + 2, 6);
          b_6.conservativeResize(b_6.rows() + 2);
          A_6.bottomRows<2>() << -Jp * cross, Jp;
          b_6.tail<2>() = shift_px;
          ++matched;
        }
      blocks_per_view.push_back(matched);
    }
    out.rounds = round + 1;
    if (used < 2) {
      out.refused = used == 0 ? "no view showed the pelvis well enough" : "only one view showed the pelvis well enough (two fix its depth)";
      return out;
    }
    double widest_deg = 0.0;
    for (std::size_t i = 0; i < rays.size(); ++i)
      for (std::size_t j = i + 1; j < rays.size(); ++j)
        widest_deg = std::max(widest_deg, std::acos(std::clamp(rays[i].dot(rays[j]), -1.0, 1.0)) * 180.0 / std::numbers::pi);
    if (widest_deg < options.min_separation_deg) {
      out.refused = "the views that showed the pelvis are " + base::quantity_text(widest_deg, "deg", 1) +
                    " apart, too close to fix its depth (needs " + base::quantity_text(options.min_separation_deg, "deg", 0) + ")";
      return out;
    }
    out.residual_px = std::sqrt(sum_sq / used);
    // The turn where blocks of two views or more pin it down, else the translation alone.
    const int views_with_blocks = static_cast<int>(std::count_if(blocks_per_view.begin(), blocks_per_view.end(), [](int n) { return n >= 3; }));
    out.blocks = static_cast<int>(A_6.rows() / 2);
    Eigen::Vector3d d_theta = Eigen::Vector3d::Zero(), d_t;
    bool turned = false;
    // The turn where the blocks pin it down: a direction they barely measure (blocks in a line
    // cannot tell a turn about that line) leaves the turn out, and the translation alone is
    // the answer. Solved as the motion it gives 50 mm from the pivot (so both halves of the
    // unknowns are millimetres).
    bool turn_measurable = false;
    constexpr double kLeverMm = 50.0;
    std::optional<Eigen::JacobiSVD<Eigen::MatrixXd>> svd;
    if (options.turn && out.blocks >= options.min_blocks && views_with_blocks >= 2) {
      Eigen::MatrixXd scaled = A_6;
      scaled.leftCols<3>() /= kLeverMm;
      svd.emplace(scaled, Eigen::ComputeThinU | Eigen::ComputeThinV);
      turn_measurable = svd->singularValues()(5) > 0.02 * svd->singularValues()(0);
    }
    // The turn only once the translation has settled to a millimetre: blocks are searched
    // ±3 matched pixels about their view's shift, so before that they measure the
    // translation's error, not the turn.
    if (turn_measurable && translation_settled) {
      svd->setThreshold(options.truncate_below);
      const Eigen::VectorXd x = svd->solve(b_6);
      // At most two degrees a round: a linearized turn is good to a few degrees, and blocks
      // are matched within ±3 pixels, so a large step overshoots and the rounds swing.
      const double scale = std::min(1.0, (2.0 * std::numbers::pi / 180.0) / std::max(x.head<3>().norm() / kLeverMm, 1e-12));
      const Eigen::Matrix<double, 6, 1> step = scale * x;
      if (step.dot(last_turning_step) < 0.0) damping *= 0.5;
      last_turning_step = step;
      d_theta = damping * step.head<3>() / kLeverMm;
      d_t = damping * step.tail<3>();
      turned = true;
    }
    if (!turned) d_t = A_t.colPivHouseholderQr().solve(b_t);
    out.turned = out.turned || turned;
    if (!turned && d_t.norm() < 1.0) translation_settled = true;
    const double angle = d_theta.norm();
    if (angle > 0.0) R = Eigen::AngleAxisd(angle, d_theta / angle).toRotationMatrix() * R;
    t += d_t;
    const double turn_deg = Eigen::AngleAxisd(R).angle() * 180.0 / std::numbers::pi;
    if (t.norm() > 2.0 * options.max_shift_mm || turn_deg > options.max_turn_deg) {
      out.refused = "the views disagree: they would move the pelvis " + base::quantity_text(t.norm(), "mm", 0) + " and turn it " +
                    base::quantity_text(turn_deg, "deg", 1);
      return out;
    }
    // Settled when the step moves no bone by more than settled_mm, the turn included once it
    // has been solved for (else the translation alone, where the turn is not measurable).
    const bool complete = turned || (!turn_measurable && !out.turned);
    if (d_t.norm() + angle * extent_mm < options.settled_mm && complete) {
      out.found = true;
      break;
    }
  }
  if (!out.found) {
    out.refused = "the pose did not settle in " + std::to_string(options.max_rounds) + " rounds (the last moved a bone by more than " +
                  base::quantity_text(options.settled_mm, "mm") + ")";
    return out;
  }
  out.shift_mm = t;
  out.rotation = R;
  return out;
}

}  // namespace evar::geometry
