#include "evar/overlay/mesh_preview.hpp"
#include "perspective_projection.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "evar/overlay/view_projection.hpp"
#include "evar/sim/example_scene.hpp"
#include "evar/sim/tube_mesh.hpp"

namespace {

using evar::geometry::TriangleMesh;
using evar::overlay::Bgr;
using evar::overlay::ComparisonPicture;
using evar::overlay::Image;
using evar::overlay::MeshLayer;
using evar::overlay::OrthographicProjection;
using evar::overlay::PreviewOptions;
using evar::overlay::StandardView;
using Eigen::Vector2d;
using Eigen::Vector3d;

const Bgr kBlack{0, 0, 0};
const Bgr kRed{0, 0, 255};

TriangleMesh triangle(const Vector3d& a, const Vector3d& b, const Vector3d& c) {
  TriangleMesh mesh;
  mesh.V.resize(3, 3);
  mesh.V << a.transpose(), b.transpose(), c.transpose();
  mesh.F.resize(1, 3);
  mesh.F << 0, 1, 2;
  return mesh;
}

// Axis-aligned square in the coronal plane (y = 0), two triangles; x and z ranges in mm.
TriangleMesh coronal_square(double x0, double x1, double z0, double z1) {
  TriangleMesh mesh;
  mesh.V.resize(4, 3);
  mesh.V << x0, 0, z0, x1, 0, z0, x1, 0, z1, x0, 0, z1;
  mesh.F.resize(2, 3);
  mesh.F << 0, 1, 2, 0, 2, 3;
  return mesh;
}

// Vertical vessel segment: 60 mm long along z, radius 6 mm, centred on `centre`.
TriangleMesh vessel(const Vector3d& centre) {
  const std::vector<Vector3d> line{centre - Vector3d(0, 0, 30), centre + Vector3d(0, 0, 30)};
  return evar::sim::tube_mesh(line, [](double) { return 6.0; });
}

MeshLayer opaque_layer(TriangleMesh mesh, Bgr colour = kRed) {
  return {"", {std::move(mesh)}, colour, 1.0, false, 1};
}

// Sum over `rect` of (r - g) / 255 per pixel, and its centroid: on a grey/black picture
// only the red test layer contributes, in proportion to its coverage.
struct RedMass {
  double mass = 0.0;
  Vector2d centroid = Vector2d::Zero();
};
RedMass red_mass(const Image& image, int x0, int y0, int width, int height) {
  RedMass m;
  for (int y = y0; y < y0 + height; ++y)
    for (int x = x0; x < x0 + width; ++x) {
      const Bgr c = image.at(x, y);
      const double w = std::max(0, c.r - c.g) / 255.0;
      m.mass += w;
      m.centroid += w * Vector2d(x - x0, y - y0);
    }
  if (m.mass > 0.0) m.centroid /= m.mass;
  return m;
}

std::filesystem::path fresh_temp_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("evar_overlay_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// ---------------------------------------------------------------------------------------
// View projections

TEST(ViewProjection, ApShowsPatientLeftOnImageRightAndSuperiorUp) {
  const Eigen::AlignedBox3d box(Vector3d(-50, -50, -50), Vector3d(50, 50, 50));
  const auto ap = OrthographicProjection::fit(StandardView::AP, box, 0.5, 300, 300);
  const Vector2d patient_left = ap.project({30, 0, 0}), patient_right = ap.project({-30, 0, 0});
  EXPECT_GT(patient_left.x(), patient_right.x());
  EXPECT_NEAR(patient_left.y(), patient_right.y(), 1e-12);
  const Vector2d superior = ap.project({0, 0, 30}), inferior = ap.project({0, 0, -30});
  EXPECT_LT(superior.y(), inferior.y());  // v grows downwards
  EXPECT_NEAR(superior.x(), inferior.x(), 1e-12);
  // Antero-posterior position does not move the point, only its depth (viewer in front).
  EXPECT_TRUE(ap.project({0, -30, 0}).isApprox(ap.project({0, 30, 0})));
  EXPECT_LT(ap.depth({0, -30, 0}), ap.depth({0, 30, 0}));
}

TEST(ViewProjection, LateralShowsAnteriorOnImageLeftViewedFromPatientLeft) {
  const Eigen::AlignedBox3d box(Vector3d(-50, -50, -50), Vector3d(50, 50, 50));
  const auto lateral = OrthographicProjection::fit(StandardView::Lateral, box, 0.5, 300, 300);
  const Vector2d anterior = lateral.project({0, -30, 0}), posterior = lateral.project({0, 30, 0});
  EXPECT_LT(anterior.x(), posterior.x());
  EXPECT_LT(lateral.project({0, 0, 30}).y(), lateral.project({0, 0, -30}).y());
  // The viewer stands at the patient's left: left structures are nearer.
  EXPECT_TRUE(lateral.project({30, 0, 0}).isApprox(lateral.project({-30, 0, 0})));
  EXPECT_LT(lateral.depth({30, 0, 0}), lateral.depth({-30, 0, 0}));
}

TEST(ViewProjection, ScaleIsMillimetresPerPixelAndCentreLandsMidImage) {
  const Eigen::AlignedBox3d box(Vector3d(10, 20, 30), Vector3d(50, 60, 90));
  const auto ap = OrthographicProjection::fit(StandardView::AP, box, 0.25, 201, 101);
  EXPECT_TRUE(ap.project(box.center()).isApprox(Vector2d(100.0, 50.0)));
  const Vector2d moved = ap.project(box.center() + Vector3d(10, 0, -5)) - ap.project(box.center());
  EXPECT_NEAR(moved.x(), 40.0, 1e-9);
  EXPECT_NEAR(moved.y(), 20.0, 1e-9);
}

TEST(ViewProjection, SharedFitScaleKeepsTheBoxInsideTheMarginsOfEveryView) {
  // Tall and deep: z limits the AP panel, y (as u) the lateral one if it were wider.
  const Eigen::AlignedBox3d box(Vector3d(-80, -200, -150), Vector3d(80, 40, 150));
  const std::array views{StandardView::AP, StandardView::Lateral};
  const int w = 400, h = 700, margin = 30;
  const double s = evar::overlay::fit_mm_per_pixel(box, views, w, h, margin);
  EXPECT_NEAR(s, std::max(240.0 / (w - 2 * margin), 300.0 / (h - 2 * margin)), 1e-12);
  for (const StandardView view : views) {
    const auto p = OrthographicProjection::fit(view, box, s, w, h);
    for (int corner = 0; corner < 8; ++corner) {
      const Vector2d uv = p.project(box.corner(static_cast<Eigen::AlignedBox3d::CornerType>(corner)));
      EXPECT_GE(uv.x(), margin - 0.5 - 1e-9);
      EXPECT_LE(uv.x(), w - 0.5 - margin + 1e-9);
      EXPECT_GE(uv.y(), margin - 0.5 - 1e-9);
      EXPECT_LE(uv.y(), h - 0.5 - margin + 1e-9);
    }
  }
}

TEST(ViewProjection, RejectsAxesThatAreNotARightHandedFrameAndBadScales) {
  const evar::overlay::ViewAxes left_handed{Vector3d::UnitX(), -Vector3d::UnitZ(), -Vector3d::UnitY()};
  EXPECT_THROW(OrthographicProjection(left_handed, Vector3d::Zero(), 1.0, 10, 10), std::invalid_argument);
  const auto ap = evar::overlay::view_axes(StandardView::AP);
  EXPECT_THROW(OrthographicProjection(ap, Vector3d::Zero(), 0.0, 10, 10), std::invalid_argument);
  EXPECT_THROW(OrthographicProjection(ap, Vector3d::Zero(), 1.0, 0, 10), std::invalid_argument);
  EXPECT_THROW(evar::overlay::fit_mm_per_pixel(Eigen::AlignedBox3d(), std::array{StandardView::AP}, 100, 100, 10),
               std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// Compositing

TEST(Composite, TriangleFillCoversItsAnalyticAreaAndOnlyItsPixels) {
  const int size = 200;
  const OrthographicProjection ap(evar::overlay::view_axes(StandardView::AP), Vector3d::Zero(), 0.37, size, size);
  const std::array<Vector3d, 3> corners{Vector3d(-25.3, 0, 21.7), Vector3d(28.9, 0, 14.2), Vector3d(-7.1, 0, -30.6)};
  evar::overlay::Overlay overlay;
  overlay.layers.push_back(opaque_layer(triangle(corners[0], corners[1], corners[2])));
  Image image = Image::filled(size, size, kBlack);
  const int k = 4;
  evar::overlay::composite(image, ap, overlay, {k, 0.45});

  std::array<Vector2d, 3> px;
  for (int i = 0; i < 3; ++i) px[i] = ap.project(corners[i]);
  const auto cross = [](const Vector2d& a, const Vector2d& b) { return a.x() * b.y() - a.y() * b.x(); };
  const double area = 0.5 * std::abs(cross(px[1] - px[0], px[2] - px[0]));
  const double perimeter = (px[1] - px[0]).norm() + (px[2] - px[1]).norm() + (px[0] - px[2]).norm();
  // Signed distance (px) of a pixel centre from the nearest edge line, positive inside.
  const double orientation = cross(px[1] - px[0], px[2] - px[0]) > 0 ? 1.0 : -1.0;
  const auto inside_distance = [&](const Vector2d& q) {
    double d = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 3; ++i) {
      const Vector2d e = px[(i + 1) % 3] - px[i];
      d = std::min(d, orientation * cross(e, q - px[i]) / e.norm());
    }
    return d;
  };
  double coverage = 0.0;
  int deep_inside = 0, far_outside = 0;
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const Bgr c = image.at(x, y);
      ASSERT_EQ(c.b, 0);
      coverage += c.r / 255.0;
      const double d = inside_distance({x, y});
      // A pixel whose centre is a pixel or more from every edge is wholly covered; one a
      // pixel or more outside is untouched.
      if (d >= 1.0) {
        ++deep_inside;
        EXPECT_EQ(c.r, 255) << "interior pixel " << x << "," << y;
      } else if (d <= -1.0) {
        ++far_outside;
        EXPECT_EQ(c.r, 0) << "exterior pixel " << x << "," << y;
      }
    }
  EXPECT_GT(deep_inside, 3000);
  EXPECT_GT(far_outside, 20000);
  // Each fine sample (k x k per pixel) counts when its centre is inside, so along an edge
  // the coverage is off by at most one fine sample across: |error| <= perimeter / k.
  EXPECT_NEAR(coverage, area, perimeter / k) << "area " << area << " px^2, perimeter " << perimeter << " px";
  // And unbiased: the per-sample rounding errors along the edges cancel, leaving about
  // sqrt(#edge samples) / k^2 ~ 3 px^2 here. 0.2 % (~20 px^2) still catches a rasteriser
  // that includes both span ends (cv::fillConvexPoly: +0.5 %, half a sample per edge).
  EXPECT_NEAR(coverage, area, 0.002 * area);
}

// The fill is computed only over the part of the image the layer's bounding box touches; a
// layer running off the image must still draw, pixel for pixel, as that part of a larger
// image where it lies whole. A 240 x 160 picture and its left 100 columns, at the same
// scale and with the same pixel centres: a translucent triangle crossing the cut, and one
// wholly inside both.
TEST(Composite, ALayerRunningOffTheImageDrawsAsThatPartOfALargerImage) {
  constexpr int kWide = 240, kNarrow = 100, kRows = 160;
  const double mm_per_px = 0.37;
  // Centred so that pixel (x, y) of the narrow image is pixel (x, y) of the wide one.
  const Vector3d centre_wide = Vector3d::Zero();
  const Vector3d centre_narrow(-(kWide - kNarrow) / 2.0 * mm_per_px, 0.0, 0.0);
  const OrthographicProjection wide(evar::overlay::view_axes(StandardView::AP), centre_wide, mm_per_px, kWide, kRows);
  const OrthographicProjection narrow(evar::overlay::view_axes(StandardView::AP), centre_narrow, mm_per_px, kNarrow, kRows);
  ASSERT_LT((wide.project({3, 0, 4}) - narrow.project({3, 0, 4})).norm(), 1e-9);
  evar::overlay::Overlay overlay;
  MeshLayer across = opaque_layer(triangle({-30.3, 0, 20.1}, {9.7, 0, 14.9}, {-22.2, 0, -25.6}));
  across.fill_alpha = 0.6;
  across.outline = false;  // an outline follows the image's edge where the layer is cut
  overlay.layers.push_back(across);
  MeshLayer inside = opaque_layer(triangle({-40.1, 0, 5.3}, {-33.6, 0, 9.9}, {-36.0, 0, -2.2}), Bgr{0, 200, 0});
  inside.outline = false;
  overlay.layers.push_back(inside);
  for (const int k : {1, 3}) {
    Image big = Image::filled(kWide, kRows, kBlack), part = Image::filled(kNarrow, kRows, kBlack);
    evar::overlay::composite(big, wide, overlay, {k, 0.45});
    evar::overlay::composite(part, narrow, overlay, {k, 0.45});
    int covered = 0;
    for (int y = 0; y < kRows; ++y)
      for (int x = 0; x < kNarrow; ++x) {
        const Bgr a = big.at(x, y), b = part.at(x, y);
        ASSERT_TRUE(a.r == b.r && a.g == b.g && a.b == b.b) << "pixel " << x << "," << y << " at supersample " << k;
        covered += a.r > 0 || a.g > 0;
      }
    EXPECT_GT(covered, 1500);
    // And the wide image has the triangle's other part beyond the cut.
    int beyond = 0;
    for (int y = 0; y < kRows; ++y)
      for (int x = kNarrow; x < kWide; ++x) beyond += big.at(x, y).r > 0;
    EXPECT_GT(beyond, 300);
  }
}

// And over the part its bounding box touches it is exactly what the whole frame gives: the
// same layers once more, each with points beyond all four image edges added (triangles of
// zero area, which set no sample but stretch the box to the whole frame), must draw the
// same bytes, outlines included. A box a pixel too small on any side (e.g. without its
// padding) loses the fill's or the outline's edge there.
TEST(Composite, TheFillOverItsBoundingBoxIsTheWholeFrameFill) {
  constexpr int kCols = 200, kRows = 150;
  const OrthographicProjection ap(evar::overlay::view_axes(StandardView::AP), Vector3d::Zero(), 0.31, kCols, kRows);
  TriangleMesh stretch;  // one point beyond each edge of the 62 x 46.5 mm field, as degenerate triangles
  stretch.V.resize(4, 3);
  stretch.V << -40, 0, 0, 40, 0, 0, 0, 0, -30, 0, 0, 30;
  stretch.F.resize(4, 3);
  stretch.F << 0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 3, 3;
  const std::vector<TriangleMesh> meshes{triangle({-20.3, 0, 11.1}, {7.7, 0, 14.9}, {-12.2, 0, -15.6}),
                                         triangle({3.1, 0, 2.2}, {17.9, 0, -9.4}, {8.8, 0, -20.05}),
                                         vessel({-2.5, 0, 1.0})};
  for (const int k : {1, 2, 3}) {
    evar::overlay::Overlay tight, whole;
    for (std::size_t m = 0; m < meshes.size(); ++m) {
      const Bgr colour{static_cast<std::uint8_t>(60 * m), 180, static_cast<std::uint8_t>(250 - 70 * m)};
      tight.layers.push_back({"", {meshes[m]}, colour, 0.45, true, 2});
      whole.layers.push_back({"", {meshes[m], stretch}, colour, 0.45, true, 2});
    }
    Image a = Image::filled(kCols, kRows, {20, 30, 40}), b = Image::filled(kCols, kRows, {20, 30, 40});
    evar::overlay::composite(a, ap, tight, {k, 0.45});
    evar::overlay::composite(b, ap, whole, {k, 0.45});
    int drawn = 0, differ = 0;
    for (int y = 0; y < kRows; ++y)
      for (int x = 0; x < kCols; ++x) {
        const Bgr p = a.at(x, y), q = b.at(x, y);
        differ += p.r != q.r || p.g != q.g || p.b != q.b;
        drawn += p.r != 40 || p.g != 30 || p.b != 20;
      }
    EXPECT_EQ(differ, 0) << "supersample " << k;
    EXPECT_GT(drawn, 3000) << "supersample " << k;
  }
}

// A finite vertex near the end of the double range can project to inf / inf: the triangles
// using it are not drawn and the rest of the mesh still is. (Its NaN position used to reach
// an integer conversion, undefined behaviour that clang's -fsanitize=undefined reports and
// GCC's does not check; on x86 it happened to draw nothing, so this test states the
// behaviour rather than catching that conversion.)
TEST(Composite, AVertexWhoseProjectionIsNotFiniteIsNotDrawn) {
  evar::geometry::ProjectionMatrix P;
  // w = 2x + 0.001z + 1000 and u = 50 + 2000x / w: about 50 + 2x px near the origin, but
  // for x near 1.7e308 both u·w and w overflow to inf.
  P << 2100, 0, 0.05, 50000, 100, 2000, 0.05, 50000, 2, 0, 1e-3, 1000;
  const evar::overlay::PerspectiveProjection view(P, 100, 100);
  TriangleMesh m = triangle({-20, -15, 0}, {20, -15, 0}, {0, 20, 0});
  m.V.conservativeResize(4, 3);
  m.V.row(3) << 1.7e308, 0, 0;
  m.F.conservativeResize(2, 3);
  m.F.row(1) << 0, 1, 3;
  ASSERT_FALSE(view.project(m.V.row(3).transpose()).allFinite());
  evar::overlay::Overlay overlay, finite_only;
  overlay.layers.push_back(opaque_layer(m));
  finite_only.layers.push_back(opaque_layer(triangle({-20, -15, 0}, {20, -15, 0}, {0, 20, 0})));
  Image image = Image::filled(100, 100, kBlack), expected = Image::filled(100, 100, kBlack);
  evar::overlay::composite(image, view, overlay);
  evar::overlay::composite(expected, view, finite_only);
  int red = 0, differ = 0;
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x) {
      red += image.at(x, y).r > 0;
      differ += image.at(x, y).r != expected.at(x, y).r;
    }
  EXPECT_GT(red, 100);   // the finite triangle
  EXPECT_EQ(differ, 0);  // and nothing of the other
}

TEST(Composite, OverlappingMeshesInOneLayerAreOutlinedAsOneSilhouetteWithoutSeams) {
  const int size = 120;
  const OrthographicProjection ap(evar::overlay::view_axes(StandardView::AP), Vector3d::Zero(), 0.5, size, size);
  evar::overlay::Overlay overlay;
  // Two squares overlapping in x in [-5, 5]; the second one's left edge (x = -5) lies
  // inside the first, where a per-mesh outline would draw a seam.
  overlay.layers.push_back(
      {"", {coronal_square(-20, 5, -10, 10), coronal_square(-5, 20, -10, 10)}, kRed, 0.3, true, 1});
  Image image = Image::filled(size, size, kBlack);
  evar::overlay::composite(image, ap, overlay);
  const Vector2d seam = ap.project({-5, 0, 0}), outer = ap.project({-20, 0, 0}), inside = ap.project({-12, 0, 0});
  const auto red = [&](const Vector2d& uv) {
    return static_cast<int>(image.at(static_cast<int>(std::lround(uv.x())), static_cast<int>(std::lround(uv.y()))).r);
  };
  EXPECT_NEAR(red(inside), 0.3 * 255, 1.0);  // fill only
  EXPECT_NEAR(red(seam), red(inside), 1.0);  // no seam line
  EXPECT_GT(red(outer), 150);                 // the union's boundary is outlined
}

TEST(Composite, DrawingIntoSeveralImagesAtOnceLeavesEachAsDrawingItAlone) {
  // The roadmap layer is drawn on black and on white in one call, rasterised once; each
  // must come out byte for byte as its own call leaves it (fills, outlines, markers, labels).
  const int size = 160;
  const OrthographicProjection ap(evar::overlay::view_axes(StandardView::AP), Vector3d::Zero(), 0.5, size, size);
  evar::overlay::Overlay overlay;
  overlay.layers.push_back({"vessel", {vessel({-10, 0, 0})}, kRed, 0.35, true, 2});
  overlay.layers.push_back({"other", {coronal_square(5, 25, -20, 5)}, Bgr{255, 128, 0}, 0.5, true, 1});
  overlay.markers.push_back({Vector3d(-10, 0, 10), "ostium", "ostia", Bgr{0, 255, 255}, false, 5});
  const evar::overlay::DrawOptions draw{2, 0.45};
  Image alone_black = Image::filled(size, size, kBlack), alone_white = Image::filled(size, size, {255, 255, 255});
  evar::overlay::composite(alone_black, ap, overlay, draw);
  evar::overlay::composite(alone_white, ap, overlay, draw);
  Image black = Image::filled(size, size, kBlack), white = Image::filled(size, size, {255, 255, 255});
  Image* const both[] = {&black, &white};
  evar::overlay::composite(std::span<Image* const>(both), ap, overlay, draw);
  EXPECT_EQ(black.bgr, alone_black.bgr);
  EXPECT_EQ(white.bgr, alone_white.bgr);
  EXPECT_NE(black.bgr, Image::filled(size, size, kBlack).bgr);  // something was drawn
  Image small = Image::filled(size / 2, size / 2, kBlack);
  Image* const mixed[] = {&black, &small};
  EXPECT_THROW(evar::overlay::composite(std::span<Image* const>(mixed), ap, overlay, draw), std::invalid_argument);
}

TEST(Composite, UnreferencedVerticesAreIgnoredAndBadIndicesAreReported) {
  auto mesh = coronal_square(-10, 10, -10, 10);
  mesh.V.conservativeResize(6, 3);
  mesh.V.row(4) << 1000, 1000, 1000;  // left behind by erased faces
  mesh.V.row(5) << std::numeric_limits<double>::quiet_NaN(), 0, 0;
  ComparisonPicture picture;
  picture.overlay.layers.push_back(opaque_layer(mesh));
  const auto layout = evar::overlay::comparison_layout(picture);
  EXPECT_TRUE(layout.bounds_lps.min().isApprox(Vector3d(-10, -0.5, -10)));
  EXPECT_TRUE(layout.bounds_lps.max().isApprox(Vector3d(10, 0.5, 10)));

  picture.overlay.layers[0].meshes[0].F(1, 2) = 6;
  try {
    evar::overlay::render_comparison(picture);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("face 1 references vertex 6"), std::string::npos) << e.what();
  }
  picture.overlay.layers[0].meshes[0].F(1, 2) = 5;  // the NaN vertex
  EXPECT_THROW(evar::overlay::render_comparison(picture), std::invalid_argument);
}

TEST(Composite, RejectsAnImageWhoseBufferDoesNotMatchItsSize) {
  Image image = Image::filled(10, 10, kBlack);
  image.bgr.pop_back();
  const OrthographicProjection ap(evar::overlay::view_axes(StandardView::AP), Vector3d::Zero(), 1.0, 10, 10);
  EXPECT_THROW(evar::overlay::composite(image, ap, {}), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------
// The comparison picture

PreviewOptions fixed_scale_options(double mm_per_pixel) {
  PreviewOptions options;
  options.mm_per_pixel = mm_per_pixel;
  options.bounds_lps = Eigen::AlignedBox3d(Vector3d(-40, -40, -40), Vector3d(40, 40, 40));
  options.background = kBlack;  // keeps frame and text grey, so only the layer is red
  return options;
}

TEST(ComparisonPicture, MeshShiftedTenMillimetresMovesTenMillimetresOverScalePixels) {
  const double s = 0.3;  // 10 mm = 33.3 px: a non-integer shift exercises sub-pixel drawing
  const PreviewOptions options = fixed_scale_options(s);
  ComparisonPicture before, after;
  before.overlay.layers.push_back(opaque_layer(vessel({0, 0, 0})));
  after.overlay.layers.push_back(opaque_layer(vessel({10, 0, 0})));  // 10 mm to patient left
  const auto layout = evar::overlay::comparison_layout(before, options);
  ASSERT_EQ(layout.panels.size(), 2u);
  const Image a = evar::overlay::render_comparison(before, options);
  const Image b = evar::overlay::render_comparison(after, options);
  for (const auto& panel : layout.panels) {
    const int w = panel.projection.width(), h = panel.projection.height();
    const RedMass ma = red_mass(a, panel.x, panel.y, w, h), mb = red_mass(b, panel.x, panel.y, w, h);
    ASSERT_GT(ma.mass, 100.0);
    EXPECT_NEAR(mb.mass, ma.mass, 0.01 * ma.mass);
    const Vector2d shift = mb.centroid - ma.centroid;
    // Unbiased sampling (see the triangle test) leaves centroid errors of ~0.02 px; a
    // rasteriser biased by half a fine sample would be off by 1/(2k) = 0.125 px.
    const double tol = 0.05;
    const double expected_u = panel.view == StandardView::AP ? 10.0 / s : 0.0;
    EXPECT_NEAR(shift.x(), expected_u, tol) << evar::overlay::to_string(panel.view);
    EXPECT_NEAR(shift.y(), 0.0, tol) << evar::overlay::to_string(panel.view);
    // And the silhouette sits where the panel's projection puts the vessel.
    EXPECT_NEAR(ma.centroid.x(), panel.projection.project({0, 0, 0}).x(), tol);
    EXPECT_NEAR(ma.centroid.y(), panel.projection.project({0, 0, 0}).y(), tol);
  }
}

TEST(ComparisonPicture, WritesAPngWhoseHeaderHasThePictureSize) {
  const auto scene = evar::sim::make_example_scene();
  std::vector<TriangleMesh> meshes;
  for (const auto& v : scene.vessels) meshes.push_back(v.mesh);
  const auto picture = evar::overlay::deformation_comparison("example", meshes, meshes, scene.device,
                                                             scene.landmarks, scene.landmarks);
  const auto layout = evar::overlay::comparison_layout(picture);
  EXPECT_EQ(layout.width, 1400);
  EXPECT_GT(layout.height, 900);  // the aorto-iliac tree is tall

  const auto path = fresh_temp_dir("png") / "preview.png";
  evar::overlay::write_comparison_png(path, picture);
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 1000u);
  const std::array<unsigned char, 8> signature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  EXPECT_TRUE(std::equal(signature.begin(), signature.end(), bytes.begin()));
  EXPECT_EQ(std::string(bytes.begin() + 12, bytes.begin() + 16), "IHDR");
  const auto be32 = [&](std::size_t i) {
    return (std::uint32_t{bytes[i]} << 24) | (std::uint32_t{bytes[i + 1]} << 16) | (std::uint32_t{bytes[i + 2]} << 8) |
           std::uint32_t{bytes[i + 3]};
  };
  EXPECT_EQ(be32(16), static_cast<std::uint32_t>(layout.width));
  EXPECT_EQ(be32(20), static_cast<std::uint32_t>(layout.height));
  EXPECT_EQ(bytes[24], 8);  // bit depth
  EXPECT_EQ(bytes[25], 2);  // colour type: truecolour (BGR written as RGB)

  const Image image = evar::overlay::render_comparison(picture);
  EXPECT_EQ(image.width, layout.width);
  EXPECT_EQ(image.height, layout.height);
  EXPECT_EQ(image.bgr.size(), static_cast<std::size_t>(image.width) * image.height * 3);
}

TEST(ComparisonPicture, WritingToAnUnwritablePathThrowsNamingThePath) {
  const auto path = fresh_temp_dir("unwritable") / "no_such_dir" / "preview.png";
  ComparisonPicture picture;
  picture.overlay.layers.push_back(opaque_layer(vessel({0, 0, 0})));
  try {
    evar::overlay::write_comparison_png(path, picture);
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(ComparisonPicture, RejectsNothingToDrawAndMismatchedLandmarks) {
  EXPECT_THROW(evar::overlay::comparison_layout(ComparisonPicture{}), std::invalid_argument);
  const evar::geometry::ControlPoint p{"renal_left", Vector3d::Zero()};
  EXPECT_THROW(evar::overlay::deformation_comparison("t", {}, {}, {}, {p}, {}), std::invalid_argument);
}

}  // namespace

// A disk that fills up while a picture is written (/dev/full answers every write with
// ENOSPC): the failure names the file and says why; a device written to is never removed.
TEST(WritePng, AFullDiskIsSaidByNameAndADeviceIsNotRemoved) {
  if (!std::filesystem::exists("/dev/full")) GTEST_SKIP() << "no /dev/full here";
  const Image image = Image::filled(64, 64, kBlack);
  try {
    evar::overlay::write_png("/dev/full", image);
    ADD_FAILURE() << "a write to a full disk succeeded";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/full"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("disk full"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(std::filesystem::is_character_file("/dev/full"));
}
