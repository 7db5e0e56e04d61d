// The OpenIGTLink server against OpenIGTLink's own example client (ReceiveClient from
// Debian's openigtlink-examples, built unchanged): what 3D Slicer's side of the protocol
// decodes is what we sent.
#include "evar/overlay/igtl_server.hpp"

#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace {

using namespace evar;

// A stock client as a child process; its output (it prints to stderr) collected through a pipe.
class Client {
 public:
  explicit Client(int port, const char* program = EVAR_IGTL_RECEIVE_CLIENT) {
    int fds[2];
    if (::pipe(fds) != 0) throw std::runtime_error("pipe");
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(fds[1], STDOUT_FILENO);
      ::dup2(fds[1], STDERR_FILENO);
      ::close(fds[0]);
      const std::string p = std::to_string(port);
      ::execl(program, program, "127.0.0.1", p.c_str(), static_cast<char*>(nullptr));
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

// A raw OpenIGTLink connection, for requests the stock clients do not make and for garbage.
class RawClient {
 public:
  explicit RawClient(int port) : fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) throw std::runtime_error("connect");
    timeval t{5, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &t, sizeof t);
  }
  ~RawClient() { ::close(fd_); }
  /// A header (version 1, no timestamp, CRC 0 as for an empty body) with `body` bytes of zeros.
  void send(const std::string& type, const std::string& name, std::uint64_t announced_body = 0, std::size_t body = 0) {
    std::vector<std::uint8_t> m(58 + body, 0);
    m[1] = 1;
    std::memcpy(&m[2], type.data(), std::min<std::size_t>(type.size(), 12));
    std::memcpy(&m[14], name.data(), std::min<std::size_t>(name.size(), 20));
    for (int i = 0; i < 8; ++i) m[42 + i] = static_cast<std::uint8_t>(announced_body >> (56 - 8 * i));
    ASSERT_EQ(::write(fd_, m.data(), m.size()), static_cast<ssize_t>(m.size()));
  }
  struct Message {
    std::string type, name;
    std::vector<std::uint8_t> body;
  };
  /// The next message, or an empty type when the connection ends or 5 s pass.
  Message receive() {
    std::uint8_t h[58];
    if (!read_all(h, sizeof h)) return {};
    std::uint64_t body = 0;
    for (int i = 0; i < 8; ++i) body = (body << 8) | h[42 + i];
    Message m{text(h + 2, 12), text(h + 14, 20), std::vector<std::uint8_t>(body)};
    if (!read_all(m.body.data(), m.body.size())) return {};
    return m;
  }

 private:
  static std::string text(const std::uint8_t* p, std::size_t n) {
    std::size_t len = 0;
    while (len < n && p[len]) ++len;
    return std::string(reinterpret_cast<const char*>(p), len);
  }
  bool read_all(std::uint8_t* p, std::size_t n) {
    while (n > 0) {
      const ssize_t got = ::recv(fd_, p, n, 0);
      if (got <= 0) return false;
      p += got;
      n -= static_cast<std::size_t>(got);
    }
    return true;
  }
  int fd_;
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

geometry::TriangleMesh triangle() {
  geometry::TriangleMesh mesh;
  mesh.V.resize(3, 3);
  mesh.V << 0, 0, 0, 10, 0, 0, 0, 10, 0;
  mesh.F.resize(1, 3);
  mesh.F << 0, 1, 2;
  return mesh;
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// OpenIGTLink's PolyDataClient asks ten times, 500 ms apart, with GET_POLYDATA under its
// own name ("Client"), and takes the next message as the answer.
TEST(IgtlServer, TheStockPolyDataClientIsAnsweredEveryTimeItAsks) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 64u << 20});
  server.send_mesh("aorta", triangle());
  Client client(server.port(), EVAR_IGTL_POLYDATA_CLIENT);
  std::string out;
  for (int i = 0; i < 100 && count_of(out, "========== PolyData Contents ==========") < 10; ++i)
    out = client.read_until("never", std::chrono::milliseconds(100));
  // Once on connection (the mesh is kept for clients that come later), then once per request.
  EXPECT_GE(count_of(out, "========== PolyData Contents =========="), 10u) << out;
  EXPECT_EQ(out.find("Invalid response"), std::string::npos) << out;
  // LPS (10, 0, 0) is RAS (-10, -0, 0).
  EXPECT_NE(out.find("point[1] = (-10, "), std::string::npos) << out;
  EXPECT_GE(server.statistics().requests_answered, 9u);
}

TEST(IgtlServer, AnswersRequestsForTheLatestOfEachAndSaysWhatItDoesNotHave) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 64u << 20});
  RawClient c(server.port());
  ASSERT_TRUE(wait_for_clients(server, 1));
  c.send("GET_STATUS", "");
  auto m = c.receive();
  EXPECT_EQ(m.type, "STATUS");
  ASSERT_GE(m.body.size(), 2u);
  EXPECT_EQ(m.body[0] * 256 + m.body[1], 1) << "STATUS_OK";
  c.send("GET_IMAGE", "evarnode");  // none composited yet
  m = c.receive();
  EXPECT_EQ(m.type, "STATUS");
  EXPECT_EQ(m.body[0] * 256 + m.body[1], 4) << "STATUS_NOT_FOUND";
  EXPECT_EQ(m.name, "evarnode");

  server.send_mesh("aorta", triangle());
  server.send_mesh("iliac_left", triangle());
  server.send_points("landmarks", {{"renal_left", Eigen::Vector3d(20, 5, 30)}});
  server.send_image("evarnode", overlay::Image::filled(8, 6, {1, 2, 3}), 0.3, 0);
  for (int i = 0; i < 4; ++i) m = c.receive();  // what was broadcast, in order
  EXPECT_EQ(m.type, "IMAGE");
  c.send("GET_POLYDATA", "iliac_left");  // by name: that one
  m = c.receive();
  EXPECT_EQ(m.type, "POLYDATA");
  EXPECT_EQ(m.name, "iliac_left");
  c.send("GET_POINT", "Client");  // a name that is none of ours: all of that type
  m = c.receive();
  EXPECT_EQ(m.type, "POINT");
  EXPECT_EQ(m.name, "landmarks");
  c.send("GET_IMAGE", "");
  m = c.receive();
  EXPECT_EQ(m.type, "IMAGE");
  EXPECT_EQ(m.name, "evarnode");
  c.send("TRANSFORM", "tool", 48, 48);  // not a request: read and let go
  c.send("GET_STATUS", "");
  EXPECT_EQ(c.receive().type, "STATUS");
  const auto st = server.statistics();
  EXPECT_EQ(st.requests_answered, 6u);
  EXPECT_EQ(st.requests_ignored, 1u);
}

TEST(IgtlServer, AClientSpeakingGarbageIsLetGoAndTheOthersAreServed) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 64u << 20});
  RawClient good(server.port()), bad(server.port());
  ASSERT_TRUE(wait_for_clients(server, 2));
  bad.send("GET_IMAGE", "x", 1ULL << 40);  // announces a terabyte
  EXPECT_EQ(bad.receive().type, "") << "the connection should have been closed";
  good.send("GET_STATUS", "");
  EXPECT_EQ(good.receive().type, "STATUS");
  EXPECT_EQ(server.statistics().clients_dropped_for_garbage, 1u);
  EXPECT_EQ(server.statistics().clients, 1u);
}

TEST(IgtlServer, AClientPushingDataIsReadPastNotDisconnected) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 64u << 20});
  RawClient c(server.port());
  ASSERT_TRUE(wait_for_clients(server, 1));
  c.send("IMAGE", "slicer_volume", 3u << 20, 3u << 20);  // 3 MiB pushed at us: read past
  c.send("GET_STATUS", "");
  EXPECT_EQ(c.receive().type, "STATUS");
  EXPECT_EQ(server.statistics().clients_dropped_for_garbage, 0u);
  EXPECT_EQ(server.statistics().requests_ignored, 1u);
}

// A client that asks and asks without reading: once its backlog is full its requests wait
// unread in its socket, so the answers queued for it stay bounded.
TEST(IgtlServer, AClientThatAsksWithoutReadingCannotMakeTheServerGrow) {
  overlay::IgtlServer server({"127.0.0.1", 0, 8, 4u << 20});
  geometry::TriangleMesh big;  // about 0.6 MB as POLYDATA
  big.V = geometry::Vertices::Random(20000, 3);
  big.F.resize(20000, 3);
  for (int f = 0; f < 20000; ++f) big.F.row(f) << f, (f + 1) % 20000, (f + 2) % 20000;
  server.send_mesh("aorta", big);
  RawClient c(server.port());
  ASSERT_TRUE(wait_for_clients(server, 1));
  for (int i = 0; i < 2000; ++i) c.send("GET_POLYDATA", "aorta");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  // 4 MiB of backlog and the kernel's socket buffers hold a few dozen answers at most;
  // without the bound all 2000 (1.2 GB) would be queued.
  EXPECT_LT(server.statistics().requests_answered, 100u);
  EXPECT_GT(server.statistics().requests_answered, 0u);
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
