#pragma once
// An OpenIGTLink (protocol 1/2 messages, as 3D Slicer's OpenIGTLinkIF expects) server for
// the node's outputs: the composited frame as an IMAGE (RGB, 8 bit), the adapted vessel
// meshes as POLYDATA and the landmarks as POINT, coordinates converted from LPS to RAS.
//
// One thread accepts clients and writes to them without blocking: each client has its own
// bounded backlog, and a client that cannot keep up loses its oldest images (counted)
// rather than stalling the node. The latest meshes and landmarks are kept and sent to every
// client that connects later. Clients may also ask: GET_IMAGE, GET_POLYDATA, GET_POINT and
// GET_STATUS are answered with the latest message (a STATUS "not found" when there is
// none); while a client's backlog is full its requests wait unread. Bound to loopback
// unless told otherwise.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "evar/geometry/markups.hpp"
#include "evar/geometry/triangle_mesh.hpp"
#include "evar/overlay/mesh_preview.hpp"

namespace evar::overlay {

struct IgtlServerOptions {
  std::string bind_address = "127.0.0.1";  ///< IPv4 address; "0.0.0.0" for every interface
  int port = 18944;                         ///< Slicer's default; 0 = any free port
  std::size_t max_clients = 8;
  std::size_t backlog_bytes = 64u << 20;    ///< per client; older images beyond it are dropped
};

struct IgtlServerStatistics {
  std::size_t clients = 0, clients_ever = 0;
  std::uint64_t messages_sent = 0, images_dropped = 0, clients_refused = 0;
  std::uint64_t requests_answered = 0;           ///< GET_IMAGE, GET_POLYDATA, GET_POINT, GET_STATUS
  std::uint64_t requests_ignored = 0;            ///< other messages a client sent (read and let go)
  std::uint64_t clients_dropped_for_garbage = 0; ///< a GET_ announcing a body larger than any request has
};

class IgtlServer {
 public:
  /// Binds and listens. std::runtime_error naming the address, port and the system's
  /// reason when that fails; std::invalid_argument for an address that is not IPv4.
  explicit IgtlServer(IgtlServerOptions options = {});
  ~IgtlServer();
  IgtlServer(const IgtlServer&) = delete;
  IgtlServer& operator=(const IgtlServer&) = delete;

  /// The port listened on (the one chosen by the system when asked for 0).
  int port() const;

  /// The image to every client now connected. `mm_per_pixel` sets the IMAGE spacing.
  void send_image(const std::string& device_name, const Image& bgr, double mm_per_pixel, std::int64_t timestamp_ns);
  /// A mesh (LPS mm) as POLYDATA, to every client now and to every later one.
  void send_mesh(const std::string& device_name, const geometry::TriangleMesh& mesh);
  /// Landmarks (LPS mm) as one POINT message, to every client now and to every later one.
  void send_points(const std::string& device_name, const std::vector<geometry::ControlPoint>& points);

  IgtlServerStatistics statistics() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace evar::overlay
