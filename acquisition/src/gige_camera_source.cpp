#include "evar/acquisition/gige_camera_source.hpp"
#include "evar/acquisition/process_capabilities.hpp"

#include <arv.h>

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <utility>

#include "evar/acquisition/clock_offset.hpp"
#include "evar/acquisition/sequence_tracker.hpp"
#include "evar/acquisition/stream_state_reporter.hpp"

namespace evar::acquisition {

namespace {

using Clock = std::chrono::steady_clock;

// The most a process without CAP_NET_ADMIN may ask for as a socket's receive buffer; empty
// when /proc does not say.
std::optional<std::int64_t> receive_buffer_limit_bytes() {
  std::ifstream in("/proc/sys/net/core/rmem_max");
  std::int64_t v = 0;
  if (in >> v && v > 0) return v;
  return std::nullopt;
}

// Owns one GObject reference.
template <class T>
struct GObjectPtr {
  T* p = nullptr;
  GObjectPtr() = default;
  explicit GObjectPtr(T* q) : p(q) {}
  GObjectPtr(const GObjectPtr&) = delete;
  GObjectPtr& operator=(const GObjectPtr&) = delete;
  GObjectPtr(GObjectPtr&& o) noexcept : p(std::exchange(o.p, nullptr)) {}
  GObjectPtr& operator=(GObjectPtr&& o) noexcept {
    reset();
    p = std::exchange(o.p, nullptr);
    return *this;
  }
  ~GObjectPtr() { reset(); }
  void reset() {
    if (p) g_object_unref(p);
    p = nullptr;
  }
  T* get() const { return p; }
  explicit operator bool() const { return p != nullptr; }
};

// Turns a GError into an exception naming what was being done.
void check(GError* error, const std::string& what) {
  if (!error) return;
  std::string message = what + ": " + error->message;
  g_error_free(error);
  throw std::runtime_error(message);
}

ArvPixelFormat to_arv(PixelFormat f) {
  switch (f) {
    case PixelFormat::Mono8: return ARV_PIXEL_FORMAT_MONO_8;
    case PixelFormat::Mono12: return ARV_PIXEL_FORMAT_MONO_12;
    case PixelFormat::Mono16: return ARV_PIXEL_FORMAT_MONO_16;
  }
  return ARV_PIXEL_FORMAT_MONO_8;
}

std::string str(const char* s) { return s ? s : ""; }

// A GVSP pixel format by its GenICam name, or its code.
std::string pixel_format_name(ArvPixelFormat f) {
  switch (f) {
    case ARV_PIXEL_FORMAT_MONO_8: return "Mono8";
    case ARV_PIXEL_FORMAT_MONO_10: return "Mono10";
    case ARV_PIXEL_FORMAT_MONO_12: return "Mono12";
    case ARV_PIXEL_FORMAT_MONO_16: return "Mono16";
    case ARV_PIXEL_FORMAT_RGB_8_PACKED: return "RGB8";
    case ARV_PIXEL_FORMAT_BAYER_RG_8: return "BayerRG8";
    default: break;
  }
  char code[16];
  std::snprintf(code, sizeof code, "0x%08x", static_cast<unsigned>(f));
  return std::string("pixel format ") + code;
}

// What a buffer turned into.
enum class Outcome { Delivered, Incomplete, Refused };


}  // namespace

std::vector<GigECameraInfo> list_gige_cameras() {
  arv_update_device_list();
  std::vector<GigECameraInfo> out;
  for (unsigned i = 0; i < arv_get_n_devices(); ++i) {
    if (str(arv_get_device_protocol(i)) != "GigEVision") continue;
    out.push_back({str(arv_get_device_id(i)), str(arv_get_device_address(i)), str(arv_get_device_serial_nbr(i)),
                   str(arv_get_device_vendor(i)), str(arv_get_device_model(i))});
  }
  return out;
}

struct GigECameraSource::Impl {
  GigECameraOptions options;
  FrameCallback on_frame;

  std::thread thread;
  std::atomic<bool> stop{false};
  std::atomic<bool> control_lost{false};
  std::mutex wait_mutex;
  std::condition_variable wake;

  mutable std::mutex mutex;  // guards what other threads read
  StreamStateReporter reporter;
  GigEStatistics stats;
  SequenceStats earlier_epochs;  // frames of connections before the current one
  SequenceTracker tracker{64, 1024};
  ClockOffsetEstimator clock{256};

  // The current connection (acquisition thread only).
  GObjectPtr<ArvCamera> camera;
  GObjectPtr<ArvStream> stream;
  gulong control_lost_handler = 0;
  std::uint64_t stream_completed = 0, stream_failed = 0, stream_underruns = 0;  // this connection
  std::optional<std::uint64_t> last_raw_id;
  int expected_width = 0, expected_height = 0;  // the region the camera was set to
  std::string refusal;                          // what the last refused frame was, against what was set
  bool refused_since_delivery = false;          // refused frames came after the last delivered one
  std::uint64_t id_epoch = 0;  // unwraps 16-bit GVSP 1.x block ids (0 is never used)
  std::string streaming_reason;

  void set_state(StreamState s, const std::string& why) { reporter.set(s, why); }

  bool wait_for_stop(std::chrono::milliseconds d) {
    std::unique_lock lock(wait_mutex);
    return wake.wait_for(lock, d, [&] { return stop.load(); });
  }

  std::string resolve_device_id() {
    const auto cams = list_gige_cameras();
    const std::string& want = options.camera;
    std::string found;
    for (const auto& c : cams) {
      found += (found.empty() ? "" : ", ") + c.id + " at " + c.address;
      if (want.empty() || c.id == want || c.serial == want || c.address == want) {
        if (want.empty() && cams.size() > 1)
          throw std::runtime_error("more than one GigE camera (" + std::to_string(cams.size()) +
                                   "); name one with --camera");
        return c.id;
      }
    }
    throw std::runtime_error("no GigE camera " + (want.empty() ? std::string("found") : "matches '" + want + "'") +
                             (found.empty() ? " (none answered discovery)" : " (found: " + found + ")"));
  }

  static void on_control_lost(ArvGvDevice*, gpointer self) {
    static_cast<Impl*>(self)->control_lost = true;
  }

  void connect() {
    const std::string id = resolve_device_id();
    GError* error = nullptr;
    camera = GObjectPtr<ArvCamera>(arv_camera_new(id.c_str(), &error));
    check(error, "opening GigE camera " + id);
    ArvCamera* cam = camera.get();
    if (!arv_camera_is_gv_device(cam)) throw std::runtime_error(id + " is not a GigE Vision device");
    ArvGvDevice* device = ARV_GV_DEVICE(arv_camera_get_device(cam));
    bool loopback = false;
    if (GSocketAddress* a = arv_gv_device_get_device_address(device)) {
      loopback = g_inet_address_get_is_loopback(g_inet_socket_address_get_address(G_INET_SOCKET_ADDRESS(a)));
    }
    const bool packet_socket = options.packet_socket && !loopback && has_effective_capability(kCapNetRaw);
    if (!packet_socket) arv_gv_device_set_stream_options(device, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
    control_lost = false;
    control_lost_handler = g_signal_connect(device, "control-lost", G_CALLBACK(on_control_lost), this);

    if (options.region) {
      const Region& r = *options.region;
      arv_camera_set_region(cam, r.x, r.y, r.width, r.height, &error);
      check(error, id + ": region " + std::to_string(r.width) + "x" + std::to_string(r.height) + "+" +
                       std::to_string(r.x) + "+" + std::to_string(r.y));
    }
    arv_camera_set_pixel_format(cam, to_arv(options.pixel_format), &error);
    if (error || arv_camera_get_pixel_format(cam, nullptr) != to_arv(options.pixel_format)) {
      if (error) g_error_free(error);
      guint n = 0;
      const char** names = arv_camera_dup_available_pixel_formats_as_strings(cam, &n, nullptr);
      std::string offered;
      for (guint i = 0; i < n; ++i) offered += (i ? ", " : "") + str(names[i]);
      g_free(names);
      throw std::runtime_error(id + " does not offer pixel format " + to_string(options.pixel_format) +
                               " (it offers: " + offered + ")");
    }
    if (options.frame_rate_hz) {
      arv_camera_set_frame_rate(cam, *options.frame_rate_hz, &error);
      check(error, id + ": frame rate " + std::to_string(*options.frame_rate_hz) + " Hz");
    }
    int packet = 0;
    if (options.packet_size) {
      arv_camera_gv_set_packet_size(cam, *options.packet_size, &error);
      check(error, id + ": packet size " + std::to_string(*options.packet_size));
      packet = *options.packet_size;
    } else {
      packet = static_cast<int>(arv_camera_gv_auto_packet_size(cam, &error));
      check(error, id + ": packet size negotiation");
    }
    gint rx = 0, ry = 0;
    arv_camera_get_region(cam, &rx, &ry, &expected_width, &expected_height, &error);
    check(error, id + ": reading the region");
    const gint payload = arv_camera_get_payload(cam, &error);
    check(error, id + ": payload size");

    stream = GObjectPtr<ArvStream>(arv_camera_create_stream(cam, nullptr, nullptr, &error));
    check(error, id + ": creating the stream");
    stream_completed = stream_failed = stream_underruns = 0;  // this stream's counters start at 0
    // Packets that arrive while the stream thread waits for the CPU queue in the socket; a
    // full socket drops them and the frame is lost. Aravis's "auto" size is one payload,
    // which lasts a single frame period; ask for several frames.
    const std::int64_t want = std::clamp<std::int64_t>(std::int64_t{options.socket_buffer_frames} * payload,
                                                       std::int64_t{256} << 10, std::int64_t{256} << 20);
    const std::optional<std::int64_t> limit = receive_buffer_limit_bytes();
    const std::int64_t granted = limit ? std::min(want, *limit) : want;
    std::string note;
    if (granted < want)
      note = "receive buffer capped at " + std::to_string(granted >> 10) + " KiB by net.core.rmem_max (" +
             std::to_string(granted / std::max(1, payload)) + " frames of " + std::to_string(payload >> 10) +
             " KiB; " + std::to_string(options.socket_buffer_frames) + " wanted): raise it, see docs/SECURITY.md";
    g_object_set(stream.get(), "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED, "socket-buffer-size",
                 static_cast<gint>(want), nullptr);
    for (int i = 0; i < options.buffers; ++i)
      arv_stream_push_buffer(stream.get(), arv_buffer_new_allocate(static_cast<size_t>(payload)));
    arv_camera_set_acquisition_mode(cam, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
    check(error, id + ": continuous acquisition");
    arv_camera_start_acquisition(cam, &error);
    check(error, id + ": starting acquisition");

    last_raw_id.reset();
    refused_since_delivery = false;
    id_epoch = 0;
    std::lock_guard lock(mutex);
    stats.camera_id = id;
    stats.packet_size = packet;
    stats.socket_buffer_bytes = static_cast<int>(granted);
    stats.socket_buffer_note = note;
    streaming_reason = "GigE camera " + id + " streaming" + (note.empty() ? "" : "; " + note);
    stats.packet_socket = packet_socket;
    ++stats.connections;
    earlier_epochs = totals_locked();
    tracker.reset();
    clock.reset();  // a power-cycled camera restarted its clock
  }

  SequenceStats totals_locked() const {
    SequenceStats t = earlier_epochs;
    return t += tracker.stats();
  }

  void update_stream_counters() {
    if (!stream) return;
    guint64 c = 0, f = 0, u = 0;
    arv_stream_get_statistics(stream.get(), &c, &f, &u);
    std::lock_guard lock(mutex);
    stats.completed += c - stream_completed;
    stats.failed += f - stream_failed;
    stats.underruns += u - stream_underruns;
    stream_completed = c;
    stream_failed = f;
    stream_underruns = u;
  }

  // `camera_gone`: do not talk to it (each register access to a vanished camera waits out
  // Aravis's GVCP retries, about 10 s).
  void teardown(bool camera_gone = false) {
    update_stream_counters();
    if (camera && !camera_gone) {
      GError* error = nullptr;
      arv_camera_stop_acquisition(camera.get(), &error);  // fails when the camera is gone: fine
      if (error) g_error_free(error);
    }
    if (camera && control_lost_handler)
      g_signal_handler_disconnect(arv_camera_get_device(camera.get()), control_lost_handler);
    control_lost_handler = 0;
    stream.reset();
    camera.reset();
  }

  // A buffer that is not what the camera was set to send: counted and said, never delivered.
  Outcome refuse(std::string why) {
    refusal = std::move(why);
    std::lock_guard lock(mutex);
    ++stats.refused;
    refused_since_delivery = true;
    return Outcome::Refused;
  }

  // One buffer from the stream, turned into a Frame when it is complete and is what the
  // camera was set to send. An incomplete frame (packets lost) is counted by the stream's
  // statistics; its block id is a gap the sequence tracker counts as a drop.
  Outcome handle(ArvBuffer* buffer) {
    const ArvBufferStatus status = arv_buffer_get_status(buffer);
    if (status == ARV_BUFFER_STATUS_SIZE_MISMATCH)
      // More data than the buffers sized for what the camera was set to: it sends a larger
      // region or a wider pixel format by itself (a reset, settings changed elsewhere).
      return refuse(std::string("frames larger than the ") + to_string(options.pixel_format) + " " +
                    std::to_string(expected_width) + " x " + std::to_string(expected_height) + " it was set to");
    if (status != ARV_BUFFER_STATUS_SUCCESS) return Outcome::Incomplete;
    Frame f;
    f.host_arrival = Clock::now();
    f.format = options.pixel_format;
    f.width = arv_buffer_get_image_width(buffer);
    f.height = arv_buffer_get_image_height(buffer);
    const ArvPixelFormat sent = arv_buffer_get_image_pixel_format(buffer);
    if (sent != to_arv(options.pixel_format) || f.width != expected_width || f.height != expected_height) {
      // Pixels of another format or size under our label would be a wrong picture.
      return refuse(pixel_format_name(sent) + " " + std::to_string(f.width) + " x " + std::to_string(f.height) +
                    " frames, not the " + to_string(options.pixel_format) + " " + std::to_string(expected_width) +
                    " x " + std::to_string(expected_height) + " it was set to");
    }
    f.stride_bytes = f.width * bytes_per_pixel(f.format);
    size_t size = 0;
    const auto* data = static_cast<const std::uint8_t*>(arv_buffer_get_data(buffer, &size));
    const std::size_t need = static_cast<std::size_t>(f.stride_bytes) * static_cast<std::size_t>(f.height);
    if (f.width <= 0 || f.height <= 0 || !data || size < need) return Outcome::Incomplete;
    f.pixels.assign(data, data + need);
    const std::uint64_t raw = arv_buffer_get_frame_id(buffer);
    // GVSP 1.x block ids are 16 bits and skip 0 when they wrap.
    if (last_raw_id && raw < 0x100 && *last_raw_id > 0xFF00 && *last_raw_id <= 0xFFFF) id_epoch += 0xFFFF;
    last_raw_id = raw;
    f.sequence = id_epoch + raw;
    f.device_time_ns = static_cast<std::int64_t>(arv_buffer_get_timestamp(buffer));
    const std::int64_t host_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(f.host_arrival.time_since_epoch()).count();
    {
      std::lock_guard lock(mutex);
      // Refused frames are not drops: the count starts afresh after them (keeping its totals).
      if (refused_since_delivery) {
        earlier_epochs = totals_locked();
        tracker.reset();
        refused_since_delivery = false;
      }
      tracker.observe(f.sequence);
      clock.add(f.device_time_ns, host_ns);
      f.device_time_on_host = Clock::time_point(std::chrono::nanoseconds(clock.to_host_ns(f.device_time_ns)));
      f.device_clock = true;
    }
    set_state(StreamState::Streaming, streaming_reason);  // before the frame, which is live
    if (on_frame) on_frame(f);
    return Outcome::Delivered;
  }

  void run() {
    bool in_outage = false;
    bool retrying = false;  // the last attempt failed: its reason stands until one succeeds
    Clock::time_point outage_since{};
    while (!stop) {
      // Said before the first attempt, not before every retry: the listener would hear the
      // two reasons in turn on every try for as long as the camera is away.
      if (!retrying)
        set_state(StreamState::Connecting, "looking for GigE camera " + (options.camera.empty() ? "(any)" : options.camera));
      try {
        connect();
        retrying = false;
      } catch (const std::exception& e) {
        retrying = true;
        teardown();
        set_state(StreamState::Connecting, std::string(e.what()) + "; retrying every " +
                                               std::to_string(options.reconnect_interval.count()) + " ms");
        if (wait_for_stop(options.reconnect_interval)) break;
        continue;
      }
      if (in_outage) {
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - outage_since).count();
        std::lock_guard lock(mutex);
        stats.longest_outage_ms = std::max(stats.longest_outage_ms, ms);
        in_outage = false;
      }
      set_state(StreamState::Connecting, "GigE camera " + stats.camera_id + " open, waiting for the first frame");
      Clock::time_point last_frame = Clock::now(), last_probe = Clock::now();
      bool refusing = false;  // only refused frames since refusing_since
      Clock::time_point refusing_since{};
      Clock::time_point last_refused{};
      std::string lost;
      bool still_there = false;  // lost the stream, not the camera
      while (!stop && lost.empty()) {
        ArvBuffer* buffer = arv_stream_timeout_pop_buffer(stream.get(), 100'000);  // µs
        if (buffer) {
          const Outcome outcome = handle(buffer);
          arv_stream_push_buffer(stream.get(), buffer);
          if (outcome == Outcome::Delivered) {
            last_frame = Clock::now();
            refusing = false;
          } else if (outcome == Outcome::Refused) {
            last_refused = Clock::now();
            if (!refusing) refusing_since = last_refused;
            refusing = true;
            set_state(StreamState::Stalled, "GigE camera " + stats.camera_id + " sends " + refusal + ": frames refused");
          }
        }
        update_stream_counters();
        // Refused frames that stopped coming say nothing more: a camera gone after switching
        // its format is looked for like any silent one.
        if (refusing && Clock::now() - last_refused > options.stall_after) refusing = false;
        const auto silent = Clock::now() - last_frame;
        if (control_lost) {
          lost = "control lost (no heartbeat answer)";
        } else if (refusing && Clock::now() - refusing_since > options.probe_after) {
          // It changed its format or region by itself (a reset, another tool): set it up again.
          lost = "it sends " + refusal + "; setting it up again";
          still_there = true;
        } else if (!refusing && silent > options.probe_after && Clock::now() - last_probe > options.probe_after) {
          // A camera that stopped sending may be gone. Discovery answers within about a
          // second; a register read of a vanished camera takes Aravis's GVCP retries (~15 s).
          last_probe = Clock::now();
          bool present = false;
          for (const auto& c : list_gige_cameras()) present |= c.id == stats.camera_id;
          if (!present)
            lost = "it no longer answers discovery";
          else if (silent > 4 * options.probe_after) {
            lost = "it answers but has sent no frame for " +
                   std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(silent).count()) +
                   " ms; restarting the stream";
            still_there = true;
          }
        }
        if (lost.empty() && silent > options.stall_after && reporter.state() != StreamState::Stalled)
          set_state(StreamState::Stalled, "GigE camera " + stats.camera_id + ": no frame for " +
                                              std::to_string(options.stall_after.count()) + " ms");
      }
      if (lost.empty()) {
        teardown();
        continue;
      }
      in_outage = true;
      outage_since = Clock::now();
      {
        std::lock_guard lock(mutex);
        ++stats.outages;
      }
      set_state(StreamState::Disconnected, "GigE camera " + stats.camera_id + " lost: " + lost + "; reconnecting");
      teardown(/*camera_gone=*/!still_there);
      if (wait_for_stop(options.reconnect_interval)) break;
    }
    set_state(StreamState::Stopped, "GigE source stopped");
  }
};

GigECameraSource::GigECameraSource(GigECameraOptions options) : impl_(std::make_unique<Impl>()) {
  if (options.buffers < 2) throw std::invalid_argument("GigE: need at least 2 buffers");
  if (options.socket_buffer_frames < 1) throw std::invalid_argument("GigE: the socket buffer must hold a frame");
  if (options.frame_rate_hz && !(*options.frame_rate_hz > 0.0))
    throw std::invalid_argument("GigE: frame rate must be positive");
  if (options.region && (options.region->width <= 0 || options.region->height <= 0 || options.region->x < 0 ||
                         options.region->y < 0))
    throw std::invalid_argument("GigE: region needs a positive size and a non-negative offset");
  impl_->options = std::move(options);
}

GigECameraSource::~GigECameraSource() { stop(); }

void GigECameraSource::start(FrameCallback on_frame, StateCallback on_state) {
  if (impl_->thread.joinable()) throw std::logic_error("GigE source already started");
  impl_->on_frame = std::move(on_frame);
  impl_->reporter.listen(std::move(on_state));
  impl_->stop = false;
  impl_->thread = std::thread([this] { impl_->run(); });
}

void GigECameraSource::stop() {
  if (!impl_->thread.joinable()) return;
  {
    std::lock_guard lock(impl_->wait_mutex);
    impl_->stop = true;
  }
  impl_->wake.notify_all();
  impl_->thread.join();  // the thread reported Stopped as its last word
}

StreamState GigECameraSource::state() const {
  return impl_->reporter.state();
}

SequenceStats GigECameraSource::statistics() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->totals_locked();
}

GigEStatistics GigECameraSource::gige_statistics() const {
  std::lock_guard lock(impl_->mutex);
  GigEStatistics s = impl_->stats;
  s.frames = impl_->totals_locked();
  s.clock_offset_ns = impl_->clock.offset_ns();
  s.typical_delay_ns = impl_->clock.typical_delay_ns();
  return s;
}

std::string GigECameraSource::description() const {
  const auto& o = impl_->options;
  return "GigE camera " + (o.camera.empty() ? std::string("(the only one found)") : o.camera) + ", " +
         to_string(o.pixel_format);
}

}  // namespace evar::acquisition
