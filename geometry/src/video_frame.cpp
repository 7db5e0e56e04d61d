#include "evar/geometry/video_frame.hpp"

#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

namespace evar::geometry {

cv::Mat detector_image(const cv::Mat& video_frame, const VideoToDetector& map) {
  if (video_frame.cols != map.video_cols() || video_frame.rows != map.video_rows())
    throw std::invalid_argument("video frame " + std::to_string(video_frame.cols) + " x " +
                                std::to_string(video_frame.rows) + " is not the video mapping's " +
                                std::to_string(map.video_cols()) + " x " + std::to_string(map.video_rows()));
  cv::Mat to_video, detector;
  cv::eigen2cv(map.detector_to_video(), to_video);
  // WARP_INVERSE_MAP: the matrix takes each detector pixel to where it lies in the frame.
  cv::warpAffine(video_frame, detector, to_video, cv::Size(map.detector_cols(), map.detector_rows()),
                 cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
  return detector;
}

ProjectionMatrix projection_on_video(const ProjectionMatrix& P_detector, const VideoToDetector& map) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A.topRows<2>() = map.detector_to_video();
  return A * P_detector;
}

}  // namespace evar::geometry
