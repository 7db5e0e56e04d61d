// Sustained GigE Vision streaming over loopback: Aravis's stock fake camera
// (arv-fake-gv-camera-0.8, its own process) streams 1024x1024 Mono16 and evarnode's
// GigECameraSource receives it. Reported per run: frames, failed and dropped frames,
// underruns, the achieved rate, this process's CPU time per frame (the host-side cost of
// receiving: Aravis's stream thread plus ours; the camera runs elsewhere) and the arrival
// delay above the minimum (jitter). EVAR_GIGE_BENCH_SECONDS sets the run length (default 60).
#include <benchmark/benchmark.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "evar/acquisition/gige_camera_source.hpp"

extern char** environ;

namespace {

using namespace std::chrono_literals;
namespace acq = evar::acquisition;

// The stock fake camera as a child process, killed when this goes.
class StockCamera {
 public:
  explicit StockCamera(const std::string& serial) {
    const char* program = "/usr/bin/arv-fake-gv-camera-0.8";
    std::vector<std::string> args{program, "-i", "127.0.0.1", "-s", serial};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, program, nullptr, nullptr, argv.data(), environ) != 0)
      throw std::runtime_error(std::string("cannot start ") + program + " (install aravis-tools)");
  }
  ~StockCamera() {
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
  }

 private:
  pid_t pid_ = -1;
};

double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

void BM_GigEStream1024Mono16(benchmark::State& state) {
  const double fps = static_cast<double>(state.range(0));
  const char* env = std::getenv("EVAR_GIGE_BENCH_SECONDS");
  const double seconds = env ? std::atof(env) : 60.0;
  const std::string serial = "EVARBENCH" + std::to_string(::getpid() % 10000);
  StockCamera camera(serial);

  acq::GigECameraOptions o;
  o.camera = serial;
  o.pixel_format = acq::PixelFormat::Mono16;
  o.region = acq::Region{0, 0, 1024, 1024};
  o.frame_rate_hz = fps;
  acq::GigECameraSource source(o);
  std::mutex m;
  std::vector<double> delays_ms;
  std::uint64_t wrong_size = 0;
  bool counting = false;
  source.start(
      [&](const acq::Frame& f) {
        std::lock_guard lock(m);
        if (!counting) return;
        if (f.width != 1024 || f.height != 1024 || f.pixels.size() != 1024u * 1024u * 2u) ++wrong_size;
        delays_ms.push_back(std::chrono::duration<double, std::milli>(f.host_arrival - f.device_time_on_host).count());
      },
      nullptr);
  for (int i = 0; i < 200 && source.state() != acq::StreamState::Streaming; ++i) std::this_thread::sleep_for(50ms);
  if (source.state() != acq::StreamState::Streaming) {
    state.SkipWithError("the stock fake camera did not stream");
    return;
  }
  std::this_thread::sleep_for(1s);  // past the start
  for (auto _ : state) {
    const auto before = source.gige_statistics();
    const double cpu0 = cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    {
      std::lock_guard lock(m);
      counting = true;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    {
      std::lock_guard lock(m);
      counting = false;
    }
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = cpu_seconds() - cpu0;
    const auto after = source.gige_statistics();
    state.SetIterationTime(wall);
    std::lock_guard lock(m);
    const double n = static_cast<double>(delays_ms.size());
    std::sort(delays_ms.begin(), delays_ms.end());
    auto pct = [&](double q) { return delays_ms.empty() ? 0.0 : delays_ms[static_cast<std::size_t>(q * (n - 1))]; };
    state.counters["frames"] = n;
    state.counters["fps"] = n / wall;
    state.counters["failed"] = static_cast<double>(after.failed - before.failed);
    state.counters["underruns"] = static_cast<double>(after.underruns - before.underruns);
    state.counters["dropped"] = static_cast<double>(after.frames.dropped - before.frames.dropped);
    state.counters["wrong_size"] = static_cast<double>(wrong_size);
    state.counters["cpu_us_per_frame"] = n > 0 ? 1e6 * cpu / n : 0.0;
    state.counters["cpu_percent"] = 100.0 * cpu / wall;
    state.counters["delay_p50_ms"] = pct(0.5);
    state.counters["delay_p99_ms"] = pct(0.99);
    state.counters["delay_max_ms"] = delays_ms.empty() ? 0.0 : delays_ms.back();
  }
  source.stop();
}

BENCHMARK(BM_GigEStream1024Mono16)->Arg(30)->Arg(60)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
