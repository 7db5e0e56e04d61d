#include "evar/overlay/igtl_server.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>

#include <igtlImageMessage.h>
#include <igtlPointMessage.h>
#include <igtlPolyDataMessage.h>
#include <igtlStatusMessage.h>

#include "evar/base/unique_fd.hpp"
#include "igtl_request_reader.hpp"

namespace evar::overlay {

namespace {

using Bytes = std::shared_ptr<const std::vector<std::uint8_t>>;

std::string system_error(const std::string& what) { return what + ": " + std::strerror(errno); }

// The IGTL header's device name holds 20 bytes.
std::string device(const std::string& name) { return name.substr(0, 20); }

Bytes packed(igtl::MessageBase* m) {
  m->Pack();
  const auto* p = static_cast<const std::uint8_t*>(m->GetPackPointer());
  return std::make_shared<const std::vector<std::uint8_t>>(p, p + m->GetPackSize());
}

struct Pending {
  Bytes bytes;
  std::size_t offset = 0;
  bool image = false;
};

struct Client {
  base::UniqueFd fd;
  std::deque<Pending> backlog;
  std::size_t backlog_bytes = 0;
  IgtlRequestReader requests;
};

struct Retained {
  std::string type;  // POLYDATA or POINT
  Bytes bytes;
};

Bytes status_message(const std::string& name, int code, const std::string& text) {
  igtl::StatusMessage::Pointer msg = igtl::StatusMessage::New();
  msg->SetDeviceName(device(name).c_str());
  msg->SetCode(code);
  msg->SetSubCode(0);
  msg->SetErrorName(code == igtl::StatusMessage::STATUS_OK ? "" : "not found");
  msg->SetStatusString(text.c_str());
  return packed(msg.GetPointer());
}

}  // namespace

struct IgtlServer::Impl {
  IgtlServerOptions options;
  base::UniqueFd listener, wake;
  int port = 0;
  std::thread thread;
  std::atomic<bool> stop{false};
  mutable std::mutex m;
  std::vector<std::unique_ptr<Client>> clients;
  std::map<std::string, Retained> retained;  // device name → latest mesh / points
  Bytes latest_image;  // the last image packed (only while a client is connected)
  IgtlServerStatistics stats;

  void notify() {
    const std::uint64_t one = 1;
    (void)!::write(wake.get(), &one, sizeof one);
  }

  void enqueue(Client& c, const Bytes& bytes, bool image) {
    if (image) {
      // Old images a slow client has not started on are worth less than the new one.
      while (c.backlog_bytes + bytes->size() > options.backlog_bytes) {
        auto it = std::find_if(c.backlog.begin(), c.backlog.end(), [](const Pending& p) { return p.image && p.offset == 0; });
        if (it == c.backlog.end()) break;
        c.backlog_bytes -= it->bytes->size();
        c.backlog.erase(it);
        ++stats.images_dropped;
      }
      if (c.backlog_bytes + bytes->size() > options.backlog_bytes) {
        ++stats.images_dropped;
        return;
      }
    }
    c.backlog.push_back({bytes, 0, image});
    c.backlog_bytes += bytes->size();
  }

  void broadcast(const Bytes& bytes, bool image) {
    {
      std::lock_guard lock(m);
      for (auto& c : clients) enqueue(*c, bytes, image);
    }
    notify();
  }

  // Answers the requests among the messages a client sent; false when the client must go
  // (its stream is garbage, see IgtlRequestReader). GET_IMAGE, GET_POLYDATA, GET_POINT: the
  // latest message of that type under the device name asked for, or all of them when the
  // name is none of ours (the stock clients ask as "Client"); GET_STATUS: the node's
  // status. What is not there is answered with a STATUS saying so; anything else is read
  // and let go.
  bool answer(Client& c, const std::uint8_t* bytes, std::size_t size) {
    std::vector<IgtlMessageHeader> messages;
    const bool ok = c.requests.feed(bytes, size, messages);
    for (const IgtlMessageHeader& m : messages) {
      if (!m.request()) {
        ++stats.requests_ignored;
        continue;
      }
      const std::string wanted = m.type.substr(4);
      const std::string& name = m.device;
      std::vector<Bytes> reply;
      bool image = false;
      if (wanted == "STATUS") {
        reply.push_back(status_message(name.empty() ? "evarnode" : name, igtl::StatusMessage::STATUS_OK, "evarnode running"));
      } else if (wanted == "IMAGE") {
        if (latest_image) reply.push_back(latest_image);
        image = true;  // may be dropped like any image for a client that does not read
      } else if (wanted == "POLYDATA" || wanted == "POINT") {
        const auto it = retained.find(name);
        if (it != retained.end() && it->second.type == wanted) {
          reply.push_back(it->second.bytes);
        } else {
          for (const auto& [n, r] : retained)
            if (r.type == wanted) reply.push_back(r.bytes);
        }
      } else {
        ++stats.requests_ignored;
        continue;
      }
      if (reply.empty()) {
        reply.push_back(status_message(name, igtl::StatusMessage::STATUS_NOT_FOUND, "no " + wanted + " to send yet"));
        image = false;
      }
      for (const Bytes& b : reply) enqueue(c, b, image);
      ++stats.requests_answered;
    }
    if (!ok) ++stats.clients_dropped_for_garbage;
    return ok;
  }

  // Writes what the socket takes now; false when the client is gone.
  bool flush(Client& c) {
    while (!c.backlog.empty()) {
      Pending& p = c.backlog.front();
      const ssize_t n = ::send(c.fd.get(), p.bytes->data() + p.offset, p.bytes->size() - p.offset, MSG_NOSIGNAL);
      if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
      p.offset += static_cast<std::size_t>(n);
      if (p.offset == p.bytes->size()) {
        c.backlog_bytes -= p.bytes->size();
        c.backlog.pop_front();
        ++stats.messages_sent;
      }
    }
    return true;
  }

  void run() {
    std::vector<pollfd> fds;
    std::uint8_t sink[4096];
    while (!stop.load()) {
      fds.clear();
      fds.push_back({listener.get(), POLLIN, 0});
      fds.push_back({wake.get(), POLLIN, 0});
      {
        std::lock_guard lock(m);
        // A client whose backlog is full is not read until it has taken some: requests it
        // sends meanwhile wait in its socket, and TCP slows it down, instead of answers
        // piling up here without bound.
        for (auto& c : clients)
          fds.push_back({c->fd.get(),
                         static_cast<short>((c->backlog_bytes < options.backlog_bytes ? POLLIN : 0) |
                                            (c->backlog.empty() ? 0 : POLLOUT)),
                         0});
      }
      if (::poll(fds.data(), fds.size(), 200) < 0 && errno != EINTR) break;
      if (fds[1].revents & POLLIN) {
        std::uint64_t count;
        (void)!::read(wake.get(), &count, sizeof count);
      }
      std::lock_guard lock(m);
      // Clients first (their indices in fds match `clients` as it was when polled).
      std::vector<bool> gone(clients.size(), false);
      for (std::size_t i = 0; i < clients.size() && i + 2 < fds.size(); ++i) {
        const short ev = fds[i + 2].revents;
        Client& c = *clients[i];
        if (ev & POLLIN) {
          const ssize_t n = ::recv(c.fd.get(), sink, sizeof sink, MSG_DONTWAIT);
          if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) gone[i] = true;
          if (n > 0 && !answer(c, sink, static_cast<std::size_t>(n))) gone[i] = true;
        }
        if (ev & (POLLERR | POLLHUP | POLLNVAL)) gone[i] = true;
        if (!gone[i] && (ev & POLLOUT) && !flush(c)) gone[i] = true;
      }
      for (std::size_t i = clients.size(); i-- > 0;)
        if (gone[i]) clients.erase(clients.begin() + static_cast<std::ptrdiff_t>(i));
      if (clients.empty()) latest_image.reset();  // images are packed only while someone listens
      if (fds[0].revents & POLLIN) {
        base::UniqueFd fd(::accept4(listener.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC));
        if (fd.get() >= 0) {
          if (clients.size() >= options.max_clients) {
            ++stats.clients_refused;
          } else {
            auto c = std::make_unique<Client>();
            c->fd = std::move(fd);
            for (const auto& [name, r] : retained) enqueue(*c, r.bytes, false);
            clients.push_back(std::move(c));
            ++stats.clients_ever;
          }
        }
      }
      stats.clients = clients.size();
    }
  }
};

IgtlServer::IgtlServer(IgtlServerOptions options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(options.port));
  if (options.port < 0 || options.port > 65535)
    throw std::invalid_argument("OpenIGTLink: port " + std::to_string(options.port) + " (0 to 65535)");
  if (::inet_pton(AF_INET, options.bind_address.c_str(), &addr.sin_addr) != 1)
    throw std::invalid_argument("OpenIGTLink: bind address '" + options.bind_address + "' is not an IPv4 address");
  const std::string where = options.bind_address + ":" + std::to_string(options.port);
  impl_->listener = base::UniqueFd(::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (impl_->listener.get() < 0) throw std::runtime_error(system_error("OpenIGTLink: socket"));
  const int yes = 1;
  ::setsockopt(impl_->listener.get(), SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  if (::bind(impl_->listener.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
    throw std::runtime_error(system_error("OpenIGTLink: cannot bind " + where));
  if (::listen(impl_->listener.get(), 8) != 0) throw std::runtime_error(system_error("OpenIGTLink: cannot listen on " + where));
  socklen_t len = sizeof addr;
  ::getsockname(impl_->listener.get(), reinterpret_cast<sockaddr*>(&addr), &len);
  impl_->port = ntohs(addr.sin_port);
  impl_->wake = base::UniqueFd(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC));
  if (impl_->wake.get() < 0) throw std::runtime_error(system_error("OpenIGTLink: eventfd"));
  impl_->thread = std::thread([impl = impl_.get()] { impl->run(); });
}

IgtlServer::~IgtlServer() {
  impl_->stop = true;
  impl_->notify();
  impl_->thread.join();
}

int IgtlServer::port() const { return impl_->port; }

void IgtlServer::send_image(const std::string& name, const Image& bgr, double mm_per_pixel, std::int64_t timestamp_ns) {
  if (bgr.width <= 0 || bgr.height <= 0 || bgr.bgr.size() != static_cast<std::size_t>(bgr.width) * bgr.height * 3)
    throw std::invalid_argument("OpenIGTLink image: size and pixel count disagree");
  {
    // Images are not kept for later clients: with none connected, skip the colour swap,
    // the packing and its CRC over the whole frame.
    std::lock_guard lock(impl_->m);
    if (impl_->clients.empty()) return;
  }
  igtl::ImageMessage::Pointer msg = igtl::ImageMessage::New();
  msg->SetDeviceName(device(name).c_str());
  msg->SetDimensions(bgr.width, bgr.height, 1);
  const auto s = static_cast<float>(mm_per_pixel);
  msg->SetSpacing(s, s, 1.0f);
  msg->SetScalarTypeToUint8();
  msg->SetNumComponents(3);
  msg->SetEndian(igtl::ImageMessage::ENDIAN_LITTLE);
  if (timestamp_ns >= 0)
    msg->SetTimeStamp(static_cast<unsigned>(timestamp_ns / 1'000'000'000),
                      static_cast<unsigned>(static_cast<double>(timestamp_ns % 1'000'000'000) * 4.294967296));
  msg->AllocateScalars();
  auto* rgb = static_cast<std::uint8_t*>(msg->GetScalarPointer());
  for (std::size_t i = 0; i < bgr.bgr.size(); i += 3) {
    rgb[i] = bgr.bgr[i + 2];
    rgb[i + 1] = bgr.bgr[i + 1];
    rgb[i + 2] = bgr.bgr[i];
  }
  const Bytes bytes = packed(msg.GetPointer());
  {
    std::lock_guard lock(impl_->m);
    impl_->latest_image = bytes;
  }
  impl_->broadcast(bytes, true);
}

void IgtlServer::send_mesh(const std::string& name, const geometry::TriangleMesh& mesh) {
  igtl::PolyDataMessage::Pointer msg = igtl::PolyDataMessage::New();
  msg->SetDeviceName(device(name).c_str());
  igtl::PolyDataPointArray::Pointer points = igtl::PolyDataPointArray::New();
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i)  // LPS → RAS
    points->AddPoint(static_cast<float>(-mesh.V(i, 0)), static_cast<float>(-mesh.V(i, 1)), static_cast<float>(mesh.V(i, 2)));
  igtl::PolyDataCellArray::Pointer polygons = igtl::PolyDataCellArray::New();
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    igtlUint32 cell[3] = {static_cast<igtlUint32>(mesh.F(f, 0)), static_cast<igtlUint32>(mesh.F(f, 1)),
                          static_cast<igtlUint32>(mesh.F(f, 2))};
    polygons->AddCell(3, cell);
  }
  msg->SetPoints(points);
  msg->SetPolygons(polygons);
  const Bytes bytes = packed(msg.GetPointer());
  {
    std::lock_guard lock(impl_->m);
    impl_->retained[device(name)] = {"POLYDATA", bytes};
  }
  impl_->broadcast(bytes, false);
}

void IgtlServer::send_points(const std::string& name, const std::vector<geometry::ControlPoint>& landmarks) {
  igtl::PointMessage::Pointer msg = igtl::PointMessage::New();
  msg->SetDeviceName(device(name).c_str());
  for (const auto& p : landmarks) {
    igtl::PointElement::Pointer e = igtl::PointElement::New();
    e->SetName(p.label.substr(0, 63).c_str());
    e->SetGroupName("Landmark");
    e->SetRGBA(255, 230, 60, 255);
    e->SetPosition(static_cast<float>(-p.position_lps.x()), static_cast<float>(-p.position_lps.y()),
                   static_cast<float>(p.position_lps.z()));
    e->SetRadius(3.0f);
    msg->AddPointElement(e);
  }
  const Bytes bytes = packed(msg.GetPointer());
  {
    std::lock_guard lock(impl_->m);
    impl_->retained[device(name)] = {"POINT", bytes};
  }
  impl_->broadcast(bytes, false);
}

IgtlServerStatistics IgtlServer::statistics() const {
  std::lock_guard lock(impl_->m);
  return impl_->stats;
}

}  // namespace evar::overlay
