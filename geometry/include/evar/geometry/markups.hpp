#pragma once
// 3D Slicer markups JSON (.mrk.json): "Curve" markups for centerlines and the device,
// "Fiducial" markups for landmarks. Positions are held in patient LPS millimetres; files
// in "RAS" are converted on read (x and y negated).
#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

namespace evar::geometry {

struct ControlPoint {
  std::string label;
  Eigen::Vector3d position_lps;  ///< mm
};

struct Markup {
  std::string type;  ///< "Curve", "ClosedCurve", "Fiducial", "Line", ...
  std::string name;
  std::vector<ControlPoint> points;
};

/// All markups in the file. Throws InputError naming the file and the JSON path of the
/// offending field (e.g. markups[0].controlPoints[3].position) for malformed content,
/// unknown coordinate systems or non-finite coordinates.
std::vector<Markup> read_markups(const std::filesystem::path& path);

/// The file's one markup of type "Curve" (or "ClosedCurve"); InputError if there is none,
/// several (naming them: the first of a whole centerline tree is no vessel's centerline),
/// or it has fewer than `min_points` control points.
Markup read_curve(const std::filesystem::path& path, std::size_t min_points = 2);

/// All control points of all "Fiducial" markups in the file, labels kept.
std::vector<ControlPoint> read_fiducials(const std::filesystem::path& path);

/// Writes markups as a valid Slicer markups JSON file in LPS.
void write_markups(const std::filesystem::path& path, const std::vector<Markup>& markups);

}  // namespace evar::geometry
