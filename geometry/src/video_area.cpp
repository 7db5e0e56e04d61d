#include "evar/geometry/video_area.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace evar::geometry {

namespace {

cv::Mat grey_float(const cv::Mat& frame) {
  cv::Mat grey = frame;
  if (frame.channels() == 3) cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
  else if (frame.channels() == 4) cv::cvtColor(frame, grey, cv::COLOR_BGRA2GRAY);
  else if (frame.channels() != 1) throw std::invalid_argument("video frames must be grey or BGR");
  cv::Mat f;
  grey.convertTo(f, CV_32F);
  return f;
}

int odd(int k) { return k % 2 == 0 ? k + 1 : k; }

PixelRect rect_of(const cv::Rect& r) {
  return {static_cast<double>(r.x), static_cast<double>(r.y), static_cast<double>(r.width),
          static_cast<double>(r.height)};
}

}  // namespace

// Boxes round the text in `text` (a mask), letters merged into lines of `k`-wide gaps: each
// line's own pixels 2 px around, specks of fewer than `least_px` pixels left out.
std::vector<PixelRect> text_boxes(const cv::Mat& text, int k, int least_px) {
  cv::Mat lines;
  cv::dilate(text, lines, cv::getStructuringElement(cv::MORPH_RECT, {odd(2 * k), 3}));
  std::vector<std::vector<cv::Point>> blobs;
  cv::findContours(lines, blobs, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  const cv::Rect frame(0, 0, text.cols, text.rows);
  std::vector<PixelRect> boxes;
  for (std::size_t i = 0; i < blobs.size(); ++i) {
    // The text's own pixels in the merged line (not the merging's reach), 2 px around them.
    cv::Mat line_mask = cv::Mat::zeros(text.size(), CV_8U);
    cv::drawContours(line_mask, blobs, static_cast<int>(i), cv::Scalar(255), cv::FILLED);
    const cv::Mat own = text & line_mask;
    if (cv::countNonZero(own) < least_px) continue;
    const cv::Rect r = cv::boundingRect(own);
    boxes.push_back(rect_of((r + cv::Size(4, 4) - cv::Point(2, 2)) & frame));
  }
  return boxes;
}

VideoArea find_video_area(const std::vector<cv::Mat>& frames) {
  if (frames.empty()) throw std::invalid_argument("no frames to find the image area in");
  cv::Mat brightest = grey_float(frames.front()), darkest = brightest.clone();
  for (std::size_t k = 1; k < frames.size(); ++k) {
    if (frames[k].size() != frames.front().size())
      throw std::invalid_argument("frame " + std::to_string(k + 1) + " is " + std::to_string(frames[k].cols) + " x " +
                                  std::to_string(frames[k].rows) + ", frame 1 " + std::to_string(frames.front().cols) +
                                  " x " + std::to_string(frames.front().rows) + ": frames of one video output");
    const cv::Mat grey = grey_float(frames[k]);
    cv::max(brightest, grey, brightest);
    cv::min(darkest, grey, darkest);
  }
  VideoArea area;
  area.video_cols = brightest.cols;
  area.video_rows = brightest.rows;

  // "Not black": above the darkest level by 5 % of the way to the bright end (the 99th
  // percentile, so a few white text pixels do not set it).
  double lowest = 0.0;
  cv::minMaxLoc(brightest, &lowest);
  std::vector<float> values(brightest.begin<float>(), brightest.end<float>());
  const auto at99 = values.begin() + static_cast<std::ptrdiff_t>(values.size() * 99 / 100);
  std::nth_element(values.begin(), at99, values.end());
  const double bright = *at99;
  area.black_level = lowest;
  area.threshold = lowest + 0.05 * (bright - lowest);
  if (!(bright > lowest))
    throw std::invalid_argument("the frames are one grey level (" + std::to_string(lowest) +
                                ") throughout: no image to find (is the C-arm's video output connected and showing fluoroscopy?)");
  cv::Mat lit = brightest > area.threshold;

  // Text strokes, rulers and cross-hairs are a few pixels thick: opened away.
  const int k = odd(std::clamp(std::min(brightest.cols, brightest.rows) / 60, 5, 15));
  cv::Mat opened;
  cv::morphologyEx(lit, opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {k, k}));
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(opened, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  if (contours.empty())
    throw std::invalid_argument("nothing but thin lines and specks is brighter than the black level: no image area "
                                "(show a fluoroscopy image on the C-arm's monitor while grabbing)");
  const auto largest = std::max_element(contours.begin(), contours.end(), [](const auto& a, const auto& b) {
    return cv::contourArea(a) < cv::contourArea(b);
  });
  cv::Mat image_region = cv::Mat::zeros(lit.size(), CV_8U);
  cv::drawContours(image_region, contours, static_cast<int>(largest - contours.begin()), cv::Scalar(255), cv::FILLED);
  // An opening keeps straight edges and large circles where they are (it only rounds the
  // rectangle's corners, by less than k / 2), so the region's box is the image's.
  const cv::Rect box = cv::boundingRect(image_region);
  area.image_rect = rect_of(box);
  area.fill = static_cast<double>(cv::countNonZero(image_region)) / box.area();
  area.field_shape = area.fill < 0.875 ? FieldShape::Circle : FieldShape::Rectangle;

  // Text: lit outside the image and its rounded-off corners (with a margin of 3 px for its
  // anti-aliased edge), letters merged into lines.
  cv::Mat around = image_region.clone();
  if (area.field_shape == FieldShape::Rectangle) around(box).setTo(255);
  cv::dilate(around, around, cv::getStructuringElement(cv::MORPH_RECT, {7, 7}));
  area.text_regions = text_boxes(lit & ~around, k, 4);

  // Text and graphics burned into the image itself (a side marker, a scale, a label): the
  // X-ray image changes from frame to frame with its quantum noise, they do not. Pixels of
  // the image (clear of its edge) that never change across the frames, thin (what an opening
  // takes away, as the strokes above) and brighter than the image around them by a tenth of
  // the grey range. Frames that do not differ over more than half the image (one frame, a
  // frozen one given twice) cannot tell graphics from the image: not searched.
  if (frames.size() >= 2) {
    cv::Mat inner;
    cv::erode(image_region, inner, cv::getStructuringElement(cv::MORPH_ELLIPSE, {7, 7}));
    const cv::Mat still = (brightest - darkest <= 1e-3 * (bright - lowest)) & inner;
    const int inner_px = cv::countNonZero(inner);
    area.still_share = inner_px > 0 ? static_cast<double>(cv::countNonZero(still)) / inner_px : 1.0;
    area.image_text_searched = area.still_share <= 0.5;
    if (area.image_text_searched) {
      cv::Mat still_opened, around_mean;
      cv::morphologyEx(still, still_opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_ELLIPSE, {k, k}));
      cv::blur(brightest, around_mean, {odd(2 * k), odd(2 * k)});
      const cv::Mat brighter = brightest - around_mean > 0.1 * (bright - lowest);
      for (const PixelRect& r : text_boxes(still & ~still_opened & brighter, k, 12)) area.text_regions.push_back(r);
    }
  }
  std::sort(area.text_regions.begin(), area.text_regions.end(),
            [](const PixelRect& a, const PixelRect& b) { return a.y != b.y ? a.y < b.y : a.x < b.x; });
  return area;
}

std::string video_mapping_misfit(const cv::Mat& frame, const VideoMapping& mapping, double tolerance_px) {
  VideoArea area;
  try {
    area = find_video_area({frame});
  } catch (const std::invalid_argument&) {
    return "";  // no picture to tell by
  }
  const PixelRect& f = area.image_rect;
  const PixelRect& m = mapping.image_rect;
  struct Side {
    const char* where;
    double past_px;
  };
  const Side sides[] = {{"left of", m.x - f.x},
                        {"right of", (f.x + f.width) - (m.x + m.width)},
                        {"above", m.y - f.y},
                        {"below", (f.y + f.height) - (m.y + m.height)}};
  const Side* worst = std::max_element(std::begin(sides), std::end(sides),
                                       [](const Side& a, const Side& b) { return a.past_px < b.past_px; });
  if (!(worst->past_px > tolerance_px)) return "";
  char text[256];
  std::snprintf(text, sizeof text,
                "the image area reaches %ld px %s the mapping's image rectangle (found [%.0f, %.0f, %.0f, %.0f], mapped "
                "[%.0f, %.0f, %.0f, %.0f])",
                std::lround(worst->past_px), worst->where, f.x, f.y, f.width, f.height, m.x, m.y, m.width, m.height);
  return text;
}

VideoMapping proposed_mapping(const VideoArea& area, int rotation_deg, bool mirror) {
  VideoMapping m;
  m.video_cols = area.video_cols;
  m.video_rows = area.video_rows;
  m.image_rect = area.image_rect;
  m.field_shape = area.field_shape;
  m.text_regions = area.text_regions;
  m.rotation_deg = rotation_deg;
  m.mirror = mirror;
  if (const auto problem = video_mapping_problem(m); !problem.empty()) throw std::invalid_argument("video mapping: " + problem);
  return m;
}

}  // namespace evar::geometry
