#pragma once
// The composited video as a file: .avi is Motion-JPEG written by OpenCV's own encoder (no
// codec library needed, every player and 3D Slicer's video tools read it); .mp4 and .mkv go
// through the FFmpeg backend (MPEG-4 part 2).
#include <cstddef>
#include <filesystem>
#include <memory>

#include "evar/overlay/mesh_preview.hpp"

namespace evar::overlay {

class VideoFileWriter {
 public:
  /// Opens the file. std::invalid_argument for another extension, a size or rate that is not
  /// positive; std::runtime_error naming the path when it cannot be written.
  VideoFileWriter(const std::filesystem::path& path, double fps, int width, int height);
  ~VideoFileWriter();
  VideoFileWriter(const VideoFileWriter&) = delete;
  VideoFileWriter& operator=(const VideoFileWriter&) = delete;

  /// Appends a frame; std::invalid_argument when its size is not the file's.
  void write(const Image& frame);
  /// Finishes the file (also done by the destructor).
  void close();
  std::size_t frames() const { return frames_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::filesystem::path path_;
  int width_, height_;
  std::size_t frames_ = 0;
};

}  // namespace evar::overlay
