// The OpenIGTLink server against OpenIGTLink's own example client (ReceiveClient from
// Debian's openigtlink-examples, built unchanged): what 3D Slicer's side of the protocol
// decodes is what we sent.
#include "evar/overlay/igtl_server.hpp"

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

namespace {

using namespace evar;

// The client as a child process; its output (it prints to stderr) collected through a pipe.
class Client {
 public:
  explicit Client(int port) {
    int fds[2];
    if (::pipe(fds) != 0) throw std::runtime_error("pipe");
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], STDOUT_FILENO);
      ::dup2(fds[1], STDERR_FILENO);
      ::close(fds[0]);
      const std::string p = std::to_string(port);
      ::execl(EVAR_IGTL_RECEIVE_CLIENT, "ReceiveClient", "127.0.0.1", p.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
    ::close(fds[1]);
    out_ = fds[0];
  }
  ~Client() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    ::close(out_);
  }
  void pause() { ::kill(pid_, SIGSTOP); }
  // Reads until `needle` has appeared or `timeout` passed; everything read so far.
  std::string read_until(const std::string& needle, std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (text_.find(needle) == std::string::npos && std::chrono::steady_clock::now() < end) {
      pollfd p{out_, POLLIN, 0};
      if (::poll(&p, 1, 50) > 0) {
        char buf[4096];
        const ssize_t n = ::read(out_, buf, sizeof buf);
        if (n <= 0) break;
        text_.append(buf, static_cast<std::size_t>(n));
      }
    }
    return text_;
  }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::string text_;
};

bool wait_for_clients(const overlay::IgtlServer& s, std::size_t n) {
  for (int i = 0; i < 200 && s.statistics().clients < n; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  return s.statistics().clients >= n;
}

TEST(IgtlServer, TheStockClientReceivesImagesMeshesAndLandmarks) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 64u << 20});
  ASSERT_GT(server.port(), 0);
  // Meshes and landmarks sent before the client connects reach it on connection.
  geometry::TriangleMesh mesh;
  mesh.V.resize(3, 3);
  mesh.V << 0, 0, 0, 10, 0, 0, 0, 10, 0;
  mesh.F.resize(1, 3);
  mesh.F << 0, 1, 2;
  server.send_mesh("aorta", mesh);
  server.send_points("landmarks", {{"renal_left", Eigen::Vector3d(20, 5, 30)}});

  Client client(server.port());
  ASSERT_TRUE(wait_for_clients(server, 1)) << client.read_until("never", std::chrono::milliseconds(100));
  overlay::Image image = overlay::Image::filled(64, 48, {10, 20, 30});
  server.send_image("evarnode", image, 0.3, 1'500'000'000);
  const std::string out = client.read_until("Dimensions", std::chrono::seconds(5));
  EXPECT_NE(out.find("Receiving : POLYDATA"), std::string::npos) << out;
  EXPECT_NE(out.find("Receiving POINT data type."), std::string::npos) << out;
  EXPECT_NE(out.find("Name      : renal_left"), std::string::npos) << out;
  // LPS (20, 5, 30) is RAS (-20, -5, 30).
  EXPECT_NE(out.find("Position  : ( -20.000000, -5.000000, 30.000000 )"), std::string::npos) << out;
  EXPECT_NE(out.find("Receiving IMAGE data type."), std::string::npos) << out;
  EXPECT_NE(out.find("Device Name           : evarnode"), std::string::npos) << out;
  const std::string rest = client.read_until("Sub-Volume offset", std::chrono::seconds(2));
  EXPECT_NE(rest.find("(64, 48, 1)"), std::string::npos) << rest;
  EXPECT_GE(server.statistics().messages_sent, 3u);
}

TEST(IgtlServer, BindsLoopbackAndSaysWhyItCannotListen) {
  overlay::IgtlServer first({"127.0.0.1", 0, 8, 1u << 20});
  try {
    overlay::IgtlServer second({"127.0.0.1", first.port(), 8, 1u << 20});
    FAIL() << "a second server on the same port";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(first.port())), std::string::npos) << e.what();
  }
  EXPECT_THROW(overlay::IgtlServer({"localhost", 0, 8, 1u << 20}), std::invalid_argument);
}

// A client that never reads must not hold the node up: its backlog is bounded, old images
// are dropped and counted, and sending returns at once.
TEST(IgtlServer, ASlowClientLosesOldImagesInsteadOfStallingTheSender) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 4u << 20});
  Client client(server.port());
  ASSERT_TRUE(wait_for_clients(server, 1));
  client.pause();  // connected, reading nothing
  const overlay::Image big = overlay::Image::filled(1024, 1024, {1, 2, 3});
  for (int i = 0; i < 40; ++i) server.send_image("evarnode", big, 0.3, i);
  // 40 images of 3 MB: a 4 MB backlog and the socket buffers hold a few; the rest were
  // dropped (oldest first), and every send returned.
  EXPECT_GE(server.statistics().images_dropped, 30u);
  EXPECT_EQ(server.statistics().clients, 1u);
}

}  // namespace
