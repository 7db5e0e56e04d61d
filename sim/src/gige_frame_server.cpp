#include "evar/sim/gige_frame_server.hpp"

#include <arv.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace evar::sim {

// Called by the fake camera's thread for every frame it sends. Its buffer's received size
// is not set yet at this point, so the image size comes from the buffer's image header.
struct GigEFrameServerFill {
  static void fill(ArvBuffer* buffer, void* self, guint32, guint32, ArvPixelFormat format) {
    auto* data = static_cast<std::uint8_t*>(const_cast<void*>(arv_buffer_get_data(buffer, nullptr)));
    const int w = arv_buffer_get_image_width(buffer), h = arv_buffer_get_image_height(buffer);
    if (data && w > 0 && h > 0)
      static_cast<GigEFrameServer*>(self)->paint(data, w, h, format == ARV_PIXEL_FORMAT_MONO_8 ? 8
                                                              : format == ARV_PIXEL_FORMAT_MONO_12 ? 12
                                                                                                    : 16);
  }
};

GigEFrameServer::GigEFrameServer(const std::string& serial, const std::string& interface) : serial_(serial) {
  camera_ = arv_gv_fake_camera_new(interface.c_str(), serial.c_str());
  if (!camera_ || !arv_gv_fake_camera_is_running(camera_)) {
    if (camera_) g_object_unref(camera_);
    throw std::runtime_error("GigE frame server: no GigE Vision camera could start on interface '" + interface +
                             "' (does it exist? is another camera using UDP port 3956 there?)");
  }
  arv_fake_camera_set_fill_pattern(arv_gv_fake_camera_get_fake_camera(camera_), &GigEFrameServerFill::fill, this);
}

GigEFrameServer::~GigEFrameServer() { g_object_unref(camera_); }  // stops the camera's threads first

void GigEFrameServer::set_packet_loss(double probability) {
  if (!(probability >= 0.0 && probability <= 1.0))
    throw std::invalid_argument("GigE frame server: packet loss must be a probability from 0 to 1");
  g_object_set(camera_, "gvsp-lost-ratio", probability, nullptr);
}

void GigEFrameServer::switch_pixel_format(acquisition::PixelFormat format) {
  ArvPixelFormat code = ARV_PIXEL_FORMAT_MONO_16;
  switch (format) {
    case acquisition::PixelFormat::Mono8: code = ARV_PIXEL_FORMAT_MONO_8; break;
    case acquisition::PixelFormat::Mono12: code = ARV_PIXEL_FORMAT_MONO_12; break;
    case acquisition::PixelFormat::Mono16: code = ARV_PIXEL_FORMAT_MONO_16; break;
  }
  arv_fake_camera_write_register(arv_gv_fake_camera_get_fake_camera(camera_), ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT,
                                 code);
}

std::string GigEFrameServer::device_id() const { return "Aravis-Fake-" + serial_; }

void GigEFrameServer::show(const acquisition::Frame& frame) {
  if (frame.format != acquisition::PixelFormat::Mono16)
    throw std::invalid_argument("GigE frame server: frames must be Mono16");
  if (frame.width <= 0 || frame.height <= 0 || frame.stride_bytes < 2 * frame.width ||
      frame.pixels.size() < static_cast<std::size_t>(frame.stride_bytes) * static_cast<std::size_t>(frame.height))
    throw std::invalid_argument("GigE frame server: frame size and pixel buffer disagree");
  std::lock_guard lock(mutex_);
  width_ = frame.width;
  height_ = frame.height;
  pixels_.resize(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_));
  for (int y = 0; y < height_; ++y)
    std::memcpy(pixels_.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width_),
                frame.pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(frame.stride_bytes),
                static_cast<std::size_t>(width_) * 2);
}

void GigEFrameServer::paint(std::uint8_t* data, int w, int h, int bits) {
  const std::size_t bpp = bits > 8 ? 2 : 1;
  std::memset(data, 0, static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * bpp);
  std::lock_guard lock(mutex_);
  const int cw = std::min(w, width_), ch = std::min(h, height_);
  for (int y = 0; y < ch; ++y) {
    const std::uint16_t* src = pixels_.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width_);
    std::uint8_t* dst = data + static_cast<std::size_t>(y) * static_cast<std::size_t>(w) * bpp;
    if (bits == 16) {
      std::memcpy(dst, src, static_cast<std::size_t>(cw) * 2);  // little-endian on both sides
    } else if (bits == 12) {
      for (int x = 0; x < cw; ++x) {
        const auto v = static_cast<std::uint16_t>(src[x] >> 4);
        std::memcpy(dst + 2 * x, &v, 2);
      }
    } else {
      for (int x = 0; x < cw; ++x) dst[x] = static_cast<std::uint8_t>(src[x] >> 8);
    }
  }
  ++sent_;
}

}  // namespace evar::sim
