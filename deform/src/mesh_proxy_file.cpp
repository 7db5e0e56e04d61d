#include "evar/deform/mesh_proxy_file.hpp"

#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>

#include "evar/base/atomic_file.hpp"
#include "evar/base/quantity_text.hpp"

namespace evar::deform {
namespace {

static_assert(std::endian::native == std::endian::little, "proxy files are little-endian, as this machine must be");

// The digit is the version of the layout and of make_proxy's method: bumped whenever either
// changes, so files of another version are made anew.
constexpr std::string_view kMagic = "evarnode-proxy2\n";
// What every version's first 14 bytes are.
constexpr std::string_view kMagicStem = "evarnode-proxy";

void put_bytes(std::string& out, const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); }
template <class T>
void put(std::string& out, T value) {
  put_bytes(out, &value, sizeof value);
}

// Reads the file's bytes in order; every shortfall is the file's, named.
class Reader {
 public:
  Reader(const std::filesystem::path& file, std::string bytes) : file_(file), bytes_(std::move(bytes)) {}
  template <class T>
  T get(const char* what) {
    T value;
    take(&value, sizeof value, what);
    return value;
  }
  void take(void* p, std::size_t n, const char* what) {
    if (bytes_.size() - at_ < n)
      fail(std::string("ends inside its ") + what + " (" + std::to_string(bytes_.size()) + " bytes; written by an interrupted run?)");
    std::memcpy(p, bytes_.data() + at_, n);
    at_ += n;
  }
  std::size_t left() const { return bytes_.size() - at_; }
  [[noreturn]] void fail(const std::string& why) const { throw std::runtime_error(file_.string() + ": " + why); }

 private:
  const std::filesystem::path& file_;
  std::string bytes_;
  std::size_t at_ = 0;
};

}  // namespace

std::uint64_t mesh_fingerprint(const geometry::TriangleMesh& mesh) {
  std::uint64_t h = 14695981039346656037ull;
  const auto mix = [&h](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  for (Eigen::Index v = 0; v < mesh.V.rows(); ++v)
    for (int k = 0; k < 3; ++k) {
      const double x = mesh.V(v, k);
      mix(&x, sizeof x);
    }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const std::int32_t i = mesh.F(f, k);
      mix(&i, sizeof i);
    }
  return h;
}

void write_mesh_proxy(const std::filesystem::path& file, const MeshProxy& proxy, const geometry::TriangleMesh& fine,
                      double edge_mm) {
  if (!(proxy.edge_mm > 0.0 && proxy.edge_mm <= edge_mm))
    throw std::invalid_argument("write_mesh_proxy: the proxy says it was remeshed to " + std::to_string(proxy.edge_mm) +
                                " mm, not between 0 and the " + std::to_string(edge_mm) + " mm it is written for");
  if (proxy.bindings.size() != static_cast<std::size_t>(fine.V.rows()))
    throw std::invalid_argument("write_mesh_proxy: the proxy binds " + std::to_string(proxy.bindings.size()) +
                                " vertices, the mesh has " + std::to_string(fine.V.rows()));
  std::string out(kMagic);
  put(out, edge_mm);
  put(out, proxy.edge_mm);
  put(out, static_cast<std::uint64_t>(fine.V.rows()));
  put(out, static_cast<std::uint64_t>(fine.F.rows()));
  put(out, mesh_fingerprint(fine));
  put(out, static_cast<std::uint64_t>(proxy.coarse.V.rows()));
  put(out, static_cast<std::uint64_t>(proxy.coarse.F.rows()));
  put(out, proxy.largest_offset_mm);
  for (Eigen::Index v = 0; v < proxy.coarse.V.rows(); ++v)
    for (int k = 0; k < 3; ++k) put(out, proxy.coarse.V(v, k));
  for (Eigen::Index f = 0; f < proxy.coarse.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) put(out, static_cast<std::int32_t>(proxy.coarse.F(f, k)));
  for (const ProxyBinding& b : proxy.bindings) {
    put(out, static_cast<std::int32_t>(b.face));
    for (int k = 0; k < 3; ++k) put(out, b.barycentric[k]);
    for (int k = 0; k < 3; ++k) put(out, b.offset_in_face[k]);
  }
  base::write_file_atomically(file, out);
}

MeshProxy read_mesh_proxy(const std::filesystem::path& file, const geometry::TriangleMesh& fine, double edge_mm) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) throw std::runtime_error(file.string() + ": cannot be opened (no such file)");
  // Not read when far bigger than this mesh's proxy can be (one binding per mesh vertex and
  // a proxy of, generously, four times the mesh's vertices and faces): a wrong path to some
  // large file.
  const auto size = std::filesystem::file_size(file, ec);
  const auto largest = kMagic.size() + 72 + static_cast<std::uintmax_t>(fine.V.rows()) * (52 + 4 * 24) +
                       static_cast<std::uintmax_t>(fine.F.rows()) * 4 * 12;
  if (ec || size > largest)
    throw std::runtime_error(file.string() + ": " + (ec ? "cannot be read" : std::to_string(size) + " bytes, more than a proxy of this mesh can hold"));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error(file.string() + ": cannot be opened");
  Reader r(file, std::string(std::istreambuf_iterator<char>(in), {}));
  char magic[kMagic.size()];
  r.take(magic, sizeof magic, "header");
  const std::string_view header(magic, sizeof magic);
  if (header.substr(0, kMagicStem.size()) != kMagicStem || header.back() != '\n')
    r.fail("not an evarnode proxy file (its first 16 bytes are not \"" + std::string(kMagic.substr(0, kMagic.size() - 1)) + "\")");
  if (header != kMagic)
    r.fail("made by another version of evarnode's proxies (" + std::string(header.substr(0, header.size() - 1)) + ", this one makes " +
           std::string(kMagic.substr(0, kMagic.size() - 1)) + ")");
  const double made_for_mm = r.get<double>("edge length");
  if (!(made_for_mm == edge_mm))
    r.fail("made for proxy edges of " + base::quantity_text(made_for_mm, "mm") + ", " + base::quantity_text(edge_mm, "mm") +
           " asked");
  const double remeshed_mm = r.get<double>("remeshed edge length");
  if (!(remeshed_mm > 0.0 && remeshed_mm <= made_for_mm))
    r.fail("says it was remeshed to edges of " + base::quantity_text(remeshed_mm, "mm") + ", not between 0 and the " +
           base::quantity_text(made_for_mm, "mm") + " it was made for (damaged)");
  const auto fine_vertices = r.get<std::uint64_t>("mesh's vertex count");
  const auto fine_faces = r.get<std::uint64_t>("mesh's face count");
  const auto fingerprint = r.get<std::uint64_t>("mesh's fingerprint");
  if (fine_vertices != static_cast<std::uint64_t>(fine.V.rows()) || fine_faces != static_cast<std::uint64_t>(fine.F.rows()) ||
      fingerprint != mesh_fingerprint(fine))
    r.fail("made for another mesh (" + std::to_string(fine_vertices) + " vertices, " + std::to_string(fine_faces) +
           " faces, or the same counts with other coordinates) than the " + std::to_string(fine.V.rows()) + " vertices and " +
           std::to_string(fine.F.rows()) + " faces it is now: was the mesh edited after the scene was made?");
  const auto vertices = r.get<std::uint64_t>("proxy's vertex count");
  const auto faces = r.get<std::uint64_t>("proxy's face count");
  MeshProxy proxy;
  proxy.edge_mm = remeshed_mm;
  proxy.largest_offset_mm = r.get<double>("largest offset");
  // Sizes checked against what is left before anything is allocated for them.
  const std::uint64_t needed = vertices * 24 + faces * 12 + fine_vertices * 52;
  if (vertices > (1u << 26) || faces > (1u << 27) || needed != r.left())
    r.fail("holds " + std::to_string(r.left()) + " bytes after its header where " + std::to_string(vertices) +
           " vertices, " + std::to_string(faces) + " faces and " + std::to_string(fine_vertices) + " bindings take " +
           std::to_string(needed) + " (damaged or cut short)");
  proxy.coarse.V.resize(static_cast<Eigen::Index>(vertices), 3);
  proxy.coarse.F.resize(static_cast<Eigen::Index>(faces), 3);
  for (Eigen::Index v = 0; v < proxy.coarse.V.rows(); ++v)
    for (int k = 0; k < 3; ++k) proxy.coarse.V(v, k) = r.get<double>("vertices");
  for (Eigen::Index f = 0; f < proxy.coarse.F.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const auto i = r.get<std::int32_t>("faces");
      if (i < 0 || static_cast<std::uint64_t>(i) >= vertices)
        r.fail("face " + std::to_string(f) + " names vertex " + std::to_string(i) + " of " + std::to_string(vertices));
      proxy.coarse.F(f, k) = i;
    }
  if (!proxy.coarse.V.allFinite()) r.fail("holds a vertex that is not a finite number");
  proxy.bindings.resize(static_cast<std::size_t>(fine_vertices));
  for (std::size_t i = 0; i < proxy.bindings.size(); ++i) {
    ProxyBinding& b = proxy.bindings[i];
    b.face = r.get<std::int32_t>("bindings");
    for (int k = 0; k < 3; ++k) b.barycentric[k] = r.get<double>("bindings");
    for (int k = 0; k < 3; ++k) b.offset_in_face[k] = r.get<double>("bindings");
    if (b.face < 0 || static_cast<std::uint64_t>(b.face) >= faces || !b.barycentric.allFinite() || !b.offset_in_face.allFinite())
      r.fail("the binding of vertex " + std::to_string(i) + " names face " + std::to_string(b.face) + " of " +
             std::to_string(faces) + " or holds a number that is not finite");
  }
  // Every binding must give its vertex back on the unmoved proxy, as a proxy just made does
  // (to rounding): a damaged number anywhere in the proxy or the bindings shows here.
  const geometry::Vertices back = follow_proxy(proxy, proxy.coarse.V);
  const Eigen::Index worst = [&] {
    Eigen::Index k = 0;
    (back - fine.V).rowwise().norm().maxCoeff(&k);
    return k;
  }();
  if (const double off = (back.row(worst) - fine.V.row(worst)).norm(); !(off <= 1e-6))
    r.fail("damaged: vertex " + std::to_string(worst) + " comes back " + base::quantity_text(off, "mm") +
           " from where it is through its binding");
  return proxy;
}

}  // namespace evar::deform
