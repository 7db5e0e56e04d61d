#include "evar/geometry/xa_dicom.hpp"
#include "evar/geometry/image_header.hpp"

#include <dcmtk/config/osconfig.h>  // first, as DCMTK requires
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcfilefo.h>
#include <dcmtk/dcmdata/dcrledrg.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmjpeg/djdecode.h>
#include <dcmtk/dcmjpls/djdecode.h>
#include <dcmtk/oflog/oflog.h>

#include <cmath>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "evar/base/input_error.hpp"
#include "evar/base/input_file.hpp"
#include "evar/base/quantity_text.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry {

namespace {

// Decoders for compressed transfer syntaxes, registered once per process; DCMTK's own log
// lines (to stderr) silenced: what matters reaches the user as the InputError.
void register_decoders() {
  static std::once_flag once;
  std::call_once(once, [] {
    OFLog::configure(OFLogger::OFF_LOG_LEVEL);
    DJDecoderRegistration::registerCodecs();
    DJLSDecoderRegistration::registerCodecs();
    DcmRLEDecoderRegistration::registerCodecs();
  });
}

std::string tag_name(const DcmTagKey& key) {
  DcmTag tag(key);
  char buf[16];
  std::snprintf(buf, sizeof buf, "(%04X,%04X)", key.getGroup(), key.getElement());
  return std::string(tag.getTagName()) + " " + buf;
}

// The attribute's value `pos` as a number, whatever numeric VR it was written with.
std::optional<double> number_of(DcmItem& item, const DcmTagKey& key, unsigned long pos, bool into_sequences) {
  DcmElement* e = nullptr;
  if (item.findAndGetElement(key, e, into_sequences).bad() || !e || e->getVM() <= pos) return std::nullopt;
  switch (e->ident()) {
    case EVR_FL: {
      Float32 v;
      if (e->getFloat32(v, pos).good()) return v;
      break;
    }
    case EVR_FD:
    case EVR_DS: {
      Float64 v;
      if (e->getFloat64(v, pos).good()) return v;
      break;
    }
    case EVR_IS: {
      Sint32 v;
      if (e->getSint32(v, pos).good()) return v;
      break;
    }
    case EVR_US: {
      Uint16 v;
      if (e->getUint16(v, pos).good()) return v;
      break;
    }
    default: break;
  }
  return std::nullopt;
}

// Where a frame's attributes live: its per-frame functional groups, the shared ones, then
// the top level (classic XA).
struct Scopes {
  DcmItem* per_frame = nullptr;
  DcmItem* shared = nullptr;
  DcmDataset* top = nullptr;

  std::optional<double> find(const DcmTagKey& key, unsigned long pos = 0) const {
    if (per_frame)
      if (auto v = number_of(*per_frame, key, pos, true)) return v;
    if (shared)
      if (auto v = number_of(*shared, key, pos, true)) return v;
    return number_of(*top, key, pos, false);
  }
};

class Reader {
 public:
  Reader(const std::filesystem::path& path, Scopes scopes) : path_(path), scopes_(scopes) {}

  double require(const DcmTagKey& key, double lo, double hi, const char* unit, unsigned long pos = 0) const {
    const auto v = scopes_.find(key, pos);
    if (!v) detail::fail(path_, tag_name(key) + ": missing (needed for the view geometry)");
    check(key, *v, lo, hi, unit);
    return *v;
  }
  void check(const DcmTagKey& key, double v, double lo, double hi, const char* unit) const {
    if (!std::isfinite(v) || v < lo || v > hi) {
      char buf[160];
      std::snprintf(buf, sizeof buf, ": %g is implausible (expected %g to %g %s)", v, lo, hi, unit);
      detail::fail(path_, tag_name(key) + buf);
    }
  }

 private:
  const std::filesystem::path& path_;
  Scopes scopes_;
};

// DS values hold at most 16 characters.
std::string decimal_string(double v) {
  char buf[32];
  for (int digits = 15; digits > 1; --digits) {
    std::snprintf(buf, sizeof buf, "%.*g", digits, v);
    if (std::string(buf).size() <= 16) return buf;
  }
  throw std::invalid_argument("DICOM: cannot write " + std::to_string(v) + " as a decimal string");
}

void ok(const OFCondition& c, const std::string& what) {
  if (c.bad()) throw std::runtime_error("DICOM writer: " + what + ": " + c.text());
}

}  // namespace

XaFrame read_xa_dicom(const std::filesystem::path& path, int frame) {
  register_decoders();
  base::check_input_file(path, base::kDicomLimit);
  DcmFileFormat file;
  if (const OFCondition c = file.loadFile(OFFilename(path.c_str())); c.bad())
    detail::fail(path, std::string("not a readable DICOM file: ") + c.text());
  DcmDataset* ds = file.getDataset();

  XaFrame out;
  OFString sop;
  ds->findAndGetOFString(DCM_SOPClassUID, sop);
  out.enhanced = sop == UID_EnhancedXAImageStorage;

  const Reader top(path, Scopes{nullptr, nullptr, ds});
  out.number_of_frames = 1;
  if (OFString n; ds->findAndGetOFString(DCM_NumberOfFrames, n).good() && !n.empty()) {
    const auto frames = number_of(*ds, DCM_NumberOfFrames, 0, false);
    if (!frames) detail::fail(path, tag_name(DCM_NumberOfFrames) + ": not a number");
    top.check(DCM_NumberOfFrames, *frames, 1, 1e6, "frames");
    out.number_of_frames = static_cast<int>(*frames);
  }
  if (frame < 0 || frame >= out.number_of_frames)
    detail::fail(path, "frame " + std::to_string(frame) + " requested, the file has " +
                           std::to_string(out.number_of_frames));
  out.frame = frame;

  Scopes scopes{nullptr, nullptr, ds};
  ds->findAndGetSequenceItem(DCM_SharedFunctionalGroupsSequence, scopes.shared, 0);
  ds->findAndGetSequenceItem(DCM_PerFrameFunctionalGroupsSequence, scopes.per_frame, frame);
  const Reader r(path, scopes);

  CArmView& v = out.view;
  // A rotational run gives each frame's angles as increments (0018,1520/1521), read by
  // some as steps from the frame before and by others from the first frame: frames they
  // may have moved are refused rather than placed at one reading's angle. Any non-zero
  // increment up to this frame counts (a single value stands for every frame), as does a
  // positioner that says it was moving.
  for (const DcmTagKey& inc : {DCM_PositionerPrimaryAngleIncrement, DCM_PositionerSecondaryAngleIncrement}) {
    for (unsigned long k = 0; k <= static_cast<unsigned long>(frame); ++k) {
      const auto step = scopes.find(inc, k);
      if (!step) break;
      if (*step != 0.0)
        detail::fail(path, tag_name(inc) + ": frame " + std::to_string(frame) +
                               " of a rotational run (an angle increment up to it is not 0); its angles are not read");
    }
  }
  for (const DcmTagKey& text_key : {DCM_PositionerMotion, DCM_PositionerType, DCM_FieldOfViewHorizontalFlip}) {
    OFString value;
    if (ds->findAndGetOFString(text_key, value, 0, true).bad()) continue;  // absent: nothing claimed
    const std::string v(value.c_str());
    if (text_key == DCM_PositionerMotion && v == "DYNAMIC" && frame > 0)
      detail::fail(path, tag_name(text_key) + ": DYNAMIC; frame " + std::to_string(frame) +
                             " of a run taken while the C-arm moved has no angles of its own");
    if (text_key == DCM_PositionerType && !v.empty() && v != "CARM")
      detail::fail(path, tag_name(text_key) + ": \"" + v + "\"; only a C-arm's angles place a view (expected CARM)");
    if (text_key == DCM_FieldOfViewHorizontalFlip && v == "YES")
      detail::fail(path, tag_name(text_key) + ": YES; a mirrored image would put the roadmap on the wrong side "
                                              "(flipped fields of view are not supported)");
  }
  // A field of view turned relative to the detector does not fit the detector model.
  {
    Float64 turned = 0.0;
    if (ds->findAndGetFloat64(DCM_FieldOfViewRotation, turned, 0, true).good() && turned != 0.0) {
      char buf[160];
      std::snprintf(buf, sizeof buf, ": %g degrees; an image turned relative to the detector is not supported", turned);
      detail::fail(path, tag_name(DCM_FieldOfViewRotation) + buf);
    }
  }
  v.primary_angle_deg = r.require(DCM_PositionerPrimaryAngle, -180.0, 180.0, "degrees");
  v.secondary_angle_deg = r.require(DCM_PositionerSecondaryAngle, -90.0, 90.0, "degrees");
  v.source_to_detector_mm = r.require(DCM_DistanceSourceToDetector, 1.0, 5000.0, "mm");
  if (scopes.find(DCM_DistanceSourceToIsocenter))
    v.source_to_isocenter_mm = r.require(DCM_DistanceSourceToIsocenter, 1.0, 5000.0, "mm");
  else
    v.source_to_isocenter_mm = r.require(DCM_DistanceSourceToPatient, 1.0, 5000.0, "mm");
  if (!(v.source_to_isocenter_mm < v.source_to_detector_mm))
    detail::fail(path, "the source to isocenter distance (" + base::quantity_text(v.source_to_isocenter_mm, "mm") +
                           ") is not less than " + tag_name(DCM_DistanceSourceToDetector) + " (" +
                           base::quantity_text(v.source_to_detector_mm, "mm") + ")");
  v.row_spacing_mm = r.require(DCM_ImagerPixelSpacing, 1e-3, 10.0, "mm", 0);
  v.col_spacing_mm = r.require(DCM_ImagerPixelSpacing, 1e-3, 10.0, "mm", 1);
  const int rows = static_cast<int>(top.require(DCM_Rows, 1, 16384, "pixels"));
  const int cols = static_cast<int>(top.require(DCM_Columns, 1, 16384, "pixels"));
  if (std::int64_t{rows} * cols > kMaxImagePixels)
    detail::fail(path, std::to_string(cols) + " x " + std::to_string(rows) + " pixels a frame; at most " +
                           std::to_string(kMaxImagePixels) + " in all are read");
  v.detector_rows = rows;
  v.detector_cols = cols;

  // Pixels.
  const int samples = static_cast<int>(top.require(DCM_SamplesPerPixel, 1, 4, "samples"));
  if (samples != 1) detail::fail(path, tag_name(DCM_SamplesPerPixel) + ": colour images are not fluoroscopy (expected 1)");
  OFString photometric;
  ds->findAndGetOFString(DCM_PhotometricInterpretation, photometric);
  if (photometric != "MONOCHROME1" && photometric != "MONOCHROME2")
    detail::fail(path, tag_name(DCM_PhotometricInterpretation) + ": \"" + std::string(photometric.c_str()) +
                           "\" (expected MONOCHROME1 or MONOCHROME2)");
  const int allocated = static_cast<int>(top.require(DCM_BitsAllocated, 1, 64, "bits"));
  if (allocated != 8 && allocated != 16)
    detail::fail(path, tag_name(DCM_BitsAllocated) + ": " + std::to_string(allocated) + " (8 or 16 are supported)");
  out.bits_stored = static_cast<int>(top.require(DCM_BitsStored, 1, allocated, "bits"));
  int high_bit = out.bits_stored - 1;
  if (const auto hb = number_of(*ds, DCM_HighBit, 0, false)) {
    top.check(DCM_HighBit, *hb, out.bits_stored - 1, allocated - 1, "(bits stored - 1 to bits allocated - 1)");
    high_bit = static_cast<int>(*hb);
  }
  const int shift = high_bit + 1 - out.bits_stored;
  if (const auto sign = scopes.find(DCM_PixelRepresentation); sign && *sign != 0)
    detail::fail(path, tag_name(DCM_PixelRepresentation) + ": signed pixels (X-ray images are unsigned)");

  E_TransferSyntax xfer = ds->getOriginalXfer();
  if (ds->chooseRepresentation(EXS_LittleEndianExplicit, nullptr).bad() || !ds->canWriteXfer(EXS_LittleEndianExplicit))
    detail::fail(path, std::string("pixel data: cannot decode transfer syntax ") + DcmXfer(xfer).getXferName());
  DcmElement* pixel_data = nullptr;
  if (ds->findAndGetElement(DCM_PixelData, pixel_data).bad() || !pixel_data)
    detail::fail(path, tag_name(DCM_PixelData) + ": missing");
  const std::size_t bytes_per_pixel = static_cast<std::size_t>(allocated / 8);
  const std::size_t frame_bytes = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * bytes_per_pixel;
  const std::size_t needed = frame_bytes * static_cast<std::size_t>(out.number_of_frames);
  if (pixel_data->getLength() < needed)
    detail::fail(path, tag_name(DCM_PixelData) + ": holds " + std::to_string(pixel_data->getLength()) +
                           " bytes; " + std::to_string(out.number_of_frames) + " frames of " + std::to_string(cols) +
                           " x " + std::to_string(rows) + " need " + std::to_string(needed));
  const unsigned mask = (1u << out.bits_stored) - 1u;
  const bool invert = photometric == "MONOCHROME1";
  if (allocated == 8) {
    Uint8* data = nullptr;
    if (pixel_data->getUint8Array(data).bad() || !data) detail::fail(path, tag_name(DCM_PixelData) + ": unreadable");
    out.pixels = cv::Mat(rows, cols, CV_8UC1);
    const Uint8* src = data + frame_bytes * static_cast<std::size_t>(frame);
    for (int i = 0; i < rows; ++i)
      for (int j = 0; j < cols; ++j) {
        const unsigned x = (static_cast<unsigned>(src[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j)]) >> shift) & mask;
        out.pixels.at<std::uint8_t>(i, j) = static_cast<std::uint8_t>(invert ? mask - x : x);
      }
  } else {
    Uint16* data = nullptr;
    if (pixel_data->getUint16Array(data).bad() || !data) detail::fail(path, tag_name(DCM_PixelData) + ": unreadable");
    out.pixels = cv::Mat(rows, cols, CV_16UC1);
    const Uint16* src = data + static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * static_cast<std::size_t>(frame);
    for (int i = 0; i < rows; ++i)
      for (int j = 0; j < cols; ++j) {
        const unsigned x = (static_cast<unsigned>(src[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(j)]) >> shift) & mask;
        out.pixels.at<std::uint16_t>(i, j) = static_cast<std::uint16_t>(invert ? mask - x : x);
      }
  }
  return out;
}

void write_xa_dicom(const std::filesystem::path& path, const CArmView& view, const std::vector<cv::Mat>& frames,
                    bool enhanced, int bits_stored) {
  if (frames.empty()) throw std::invalid_argument("write_xa_dicom: no frames");
  const int type = frames.front().type();
  if (type != CV_8UC1 && type != CV_16UC1) throw std::invalid_argument("write_xa_dicom: frames must be CV_8UC1 or CV_16UC1");
  for (const auto& f : frames)
    if (f.type() != type || f.size() != frames.front().size())
      throw std::invalid_argument("write_xa_dicom: all frames must have one size and type");
  const int allocated = type == CV_8UC1 ? 8 : 16;
  if (bits_stored <= 0) bits_stored = allocated;
  if (bits_stored > allocated) throw std::invalid_argument("write_xa_dicom: bits stored exceed bits allocated");
  const int rows = frames.front().rows, cols = frames.front().cols;
  for (const auto& f : frames) {
    double largest = 0.0;
    cv::minMaxLoc(f, nullptr, &largest);
    if (largest > static_cast<double>((1u << bits_stored) - 1u))
      throw std::invalid_argument("write_xa_dicom: a pixel value exceeds " + std::to_string(bits_stored) + " bits stored");
  }

  DcmFileFormat file;
  DcmDataset* ds = file.getDataset();
  char uid[100];
  ok(ds->putAndInsertString(DCM_SOPClassUID, enhanced ? UID_EnhancedXAImageStorage : UID_XRayAngiographicImageStorage),
     "SOP class");
  ok(ds->putAndInsertString(DCM_SOPInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_INSTANCE_UID_ROOT)), "UID");
  ok(ds->putAndInsertString(DCM_StudyInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_STUDY_UID_ROOT)), "UID");
  ok(ds->putAndInsertString(DCM_SeriesInstanceUID, dcmGenerateUniqueIdentifier(uid, SITE_SERIES_UID_ROOT)), "UID");
  ok(ds->putAndInsertString(DCM_Modality, "XA"), "modality");
  ok(ds->putAndInsertString(DCM_PatientName, "EVARNODE^SIMULATED"), "patient");
  ok(ds->putAndInsertString(DCM_Manufacturer, "evarnode"), "manufacturer");
  ok(ds->putAndInsertUint16(DCM_Rows, static_cast<Uint16>(rows)), "rows");
  ok(ds->putAndInsertUint16(DCM_Columns, static_cast<Uint16>(cols)), "columns");
  ok(ds->putAndInsertUint16(DCM_SamplesPerPixel, 1), "samples");
  ok(ds->putAndInsertString(DCM_PhotometricInterpretation, "MONOCHROME2"), "photometric");
  ok(ds->putAndInsertUint16(DCM_BitsAllocated, static_cast<Uint16>(allocated)), "bits allocated");
  ok(ds->putAndInsertUint16(DCM_BitsStored, static_cast<Uint16>(bits_stored)), "bits stored");
  ok(ds->putAndInsertUint16(DCM_HighBit, static_cast<Uint16>(bits_stored - 1)), "high bit");
  ok(ds->putAndInsertUint16(DCM_PixelRepresentation, 0), "pixel representation");
  ok(ds->putAndInsertString(DCM_NumberOfFrames, std::to_string(frames.size()).c_str()), "frames");

  const std::string spacing = decimal_string(view.row_spacing_mm) + "\\" + decimal_string(view.col_spacing_mm);
  if (!enhanced) {
    ok(ds->putAndInsertString(DCM_PositionerPrimaryAngle, decimal_string(view.primary_angle_deg).c_str()), "angle");
    ok(ds->putAndInsertString(DCM_PositionerSecondaryAngle, decimal_string(view.secondary_angle_deg).c_str()), "angle");
    ok(ds->putAndInsertString(DCM_DistanceSourceToDetector, decimal_string(view.source_to_detector_mm).c_str()), "SID");
    ok(ds->putAndInsertString(DCM_DistanceSourceToPatient, decimal_string(view.source_to_isocenter_mm).c_str()), "SOD");
    ok(ds->putAndInsertString(DCM_ImagerPixelSpacing, spacing.c_str()), "spacing");
  } else {
    DcmItem* shared = nullptr;
    ok(ds->findOrCreateSequenceItem(DCM_SharedFunctionalGroupsSequence, shared, 0), "shared groups");
    DcmItem* item = nullptr;
    ok(shared->findOrCreateSequenceItem(DCM_PositionerPositionSequence, item, 0), "positioner");
    ok(item->putAndInsertString(DCM_PositionerPrimaryAngle, decimal_string(view.primary_angle_deg).c_str()), "angle");
    ok(item->putAndInsertString(DCM_PositionerSecondaryAngle, decimal_string(view.secondary_angle_deg).c_str()), "angle");
    ok(shared->findOrCreateSequenceItem(DCM_XRayGeometrySequence, item, 0), "geometry");
    ok(item->putAndInsertFloat32(DCM_DistanceSourceToIsocenter, static_cast<Float32>(view.source_to_isocenter_mm)), "SOD");
    ok(item->putAndInsertString(DCM_DistanceSourceToDetector, decimal_string(view.source_to_detector_mm).c_str()), "SID");
    ok(shared->findOrCreateSequenceItem(DCM_FramePixelDataPropertiesSequence, item, 0), "pixel properties");
    ok(item->putAndInsertString(DCM_ImagerPixelSpacing, spacing.c_str()), "spacing");
  }

  const std::size_t per_frame = static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols);
  if (allocated == 8) {
    std::vector<Uint8> data;
    data.reserve(per_frame * frames.size());
    for (const auto& f : frames)
      for (int i = 0; i < rows; ++i) data.insert(data.end(), f.ptr<Uint8>(i), f.ptr<Uint8>(i) + cols);
    if (data.size() % 2) data.push_back(0);  // even length
    ok(ds->putAndInsertUint8Array(DCM_PixelData, data.data(), static_cast<unsigned long>(data.size())), "pixels");
  } else {
    std::vector<Uint16> data;
    data.reserve(per_frame * frames.size());
    for (const auto& f : frames)
      for (int i = 0; i < rows; ++i) data.insert(data.end(), f.ptr<Uint16>(i), f.ptr<Uint16>(i) + cols);
    ok(ds->putAndInsertUint16Array(DCM_PixelData, data.data(), static_cast<unsigned long>(data.size())), "pixels");
  }
  ok(file.saveFile(OFFilename(path.c_str()), EXS_LittleEndianExplicit), "saving " + path.string());
}

}  // namespace evar::geometry
