#include "evar/overlay/video_file_writer.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>

#include <opencv2/videoio.hpp>
#include "image_mat.hpp"

namespace evar::overlay {

struct VideoFileWriter::Impl {
  cv::VideoWriter writer;
};

VideoFileWriter::VideoFileWriter(const std::filesystem::path& path, double fps, int width, int height)
    : impl_(std::make_unique<Impl>()), path_(path), width_(width), height_(height) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  int fourcc = 0, api = cv::CAP_ANY;
  if (ext == ".avi") {
    fourcc = cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
    api = cv::CAP_OPENCV_MJPEG;
  } else if (ext == ".mp4" || ext == ".mkv") {
    fourcc = cv::VideoWriter::fourcc('m', 'p', '4', 'v');
    api = cv::CAP_FFMPEG;
  } else {
    throw std::invalid_argument(path.string() + ": video files are .avi (Motion-JPEG), .mp4 or .mkv");
  }
  if (!(fps > 0) || width <= 0 || height <= 0)
    throw std::invalid_argument(path.string() + ": a video needs a positive frame rate and size");
  if (!impl_->writer.open(path.string(), api, fourcc, fps, cv::Size(width, height), true))
    throw std::runtime_error(path.string() + ": cannot write this video file (folder missing or not writable, or no " +
                             ext.substr(1) + " encoder)");
}

VideoFileWriter::~VideoFileWriter() { close(); }

void VideoFileWriter::write(const Image& frame) {
  if (frame.width != width_ || frame.height != height_)
    throw std::invalid_argument(path_.string() + ": frame " + std::to_string(frame.width) + " x " +
                                std::to_string(frame.height) + " in a " + std::to_string(width_) + " x " +
                                std::to_string(height_) + " video");
  if (!impl_->writer.isOpened()) throw std::runtime_error(path_.string() + ": the video is closed");
  impl_->writer.write(detail::wrap(frame));
  ++frames_;
}

void VideoFileWriter::close() {
  if (impl_ && impl_->writer.isOpened()) impl_->writer.release();
}

}  // namespace evar::overlay
