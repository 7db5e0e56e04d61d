#pragma once
// DICOM X-ray angiography files (XA and Enhanced XA) through DCMTK: the view geometry of a
// frame and its pixels.
//
// Geometry attributes are looked up in the frame's Per-frame Functional Groups item, then in
// the Shared Functional Groups (Enhanced XA keeps them in macros such as the Positioner
// Position, X-Ray Geometry and Frame Pixel Data Properties sequences), then at the top level
// (XA):
//   Positioner Primary Angle (0018,1510), Positioner Secondary Angle (0018,1511),
//   Distance Source to Detector (0018,1110),
//   Distance Source to Isocenter (0018,9402) or Distance Source to Patient (0018,1111),
//   Imager Pixel Spacing (0018,1164), Rows (0028,0010), Columns (0028,0011).
#include <filesystem>
#include <string>

#include <opencv2/core.hpp>

#include "evar/geometry/carm_projection.hpp"

namespace evar::geometry {

struct XaFrame {
  CArmView view;               ///< from the header (no projection matrix)
  cv::Mat pixels;              ///< CV_8UC1 or CV_16UC1; dark = attenuating (MONOCHROME1 is inverted)
  int bits_stored = 0;         ///< significant bits of each pixel (e.g. 12 of 16)
  int frame = 0;               ///< which frame of the file
  int number_of_frames = 1;
  bool enhanced = false;       ///< Enhanced XA Image Storage
};

/// Reads frame `frame` (0-based) of an XA or Enhanced XA file, uncompressed or with a
/// lossless/lossy JPEG, JPEG-LS or RLE transfer syntax. Throws InputError naming the file
/// and the missing or implausible attribute (tag and name), or why the pixels cannot be
/// used (colour, signed, more than 16 bits, frame out of range).
XaFrame read_xa_dicom(const std::filesystem::path& path, int frame = 0);

/// Writes one or more frames (all the same size, CV_8UC1 or CV_16UC1, MONOCHROME2) as an
/// XA file (angles and distances at the top level) or an Enhanced XA file (in the shared
/// functional groups), little endian explicit, uncompressed. For tests and simulated sessions.
void write_xa_dicom(const std::filesystem::path& path, const CArmView& view, const std::vector<cv::Mat>& frames,
                    bool enhanced = false, int bits_stored = 0);

}  // namespace evar::geometry
