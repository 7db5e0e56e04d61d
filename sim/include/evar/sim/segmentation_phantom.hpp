#pragma once
// An aorto-iliac segmentation as a segmentation tool exports it, with its truth: a label
// volume (an aneurysmal aorta, both iliacs, renal and internal iliac stubs) voxelised at a
// CT's anisotropic spacing and turned into one connected surface by VTK's marching cubes,
// unsmoothed, so it carries the voxel staircase and the slivers such surfaces have; written
// in patient LPS, in RAS, or in the image's own axes.
#include <Eigen/Core>
#include <string>
#include <vector>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/polyline.hpp"
#include "evar/geometry/triangle_mesh.hpp"

namespace evar::sim {

/// The frame the surface's coordinates are in.
enum class PhantomFrame {
  Lps,    ///< patient LPS (DICOM, 3D Slicer's files)
  Ras,    ///< patient RAS (3D Slicer's older model files)
  Image,  ///< a coronal volume's own axes, "LIP": x to the patient's left, y to the feet, z to the back
};

struct SegmentationPhantomOptions {
  Eigen::Vector3d spacing_mm{0.8, 0.8, 1.5};  ///< voxel size along LPS x, y, z
  PhantomFrame frame = PhantomFrame::Lps;
  bool side_branches = true;  ///< renal and internal iliac stubs
  /// The label volume's extent from foot to head (LPS z, mm): the whole phantom by default;
  /// less crops it as a segmentation cropped to its region of interest is (flat caps there).
  /// The truth (paths, ostia) is not cropped with it: below -20 mm the internal iliac stubs
  /// go, above 105 mm the aorta's top.
  double lowest_z_mm = -100.0, highest_z_mm = 133.0;
};

struct SegmentationPhantom {
  geometry::TriangleMesh surface;  ///< in the options' frame
  std::string axes;                ///< that frame's code: "LPS", "RAS", "LIP"
  Eigen::Matrix3d to_lps = Eigen::Matrix3d::Identity();  ///< surface coordinates -> LPS (a rotation)
  /// The truth in LPS: centerline paths from the aortic inlet to each outlet (iliac right,
  /// iliac left, then the stubs), and the ostia where the stubs leave their parents' walls.
  std::vector<geometry::Polyline> paths;
  std::vector<geometry::ControlPoint> ostia;  ///< renal_right, renal_left, internal_iliac_right, internal_iliac_left
  Eigen::Vector3d bifurcation = Eigen::Vector3d::Zero();  ///< where the iliac axes leave the aorta's
};

SegmentationPhantom make_segmentation_phantom(const SegmentationPhantomOptions& options = {});

}  // namespace evar::sim
