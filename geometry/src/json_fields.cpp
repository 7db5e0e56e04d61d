#include "evar/geometry/json_fields.hpp"

#include <cmath>
#include <sstream>

#include "evar/base/input_file.hpp"
#include "mesh_formats.hpp"

namespace evar::geometry::detail {

using nlohmann::json;

void bad_field(const std::filesystem::path& file, const std::string& field, const std::string& what) {
  fail(file, field + ": " + what);
}

json parse_json_file(const std::filesystem::path& file) {
  const std::string text = base::read_input_file(file, base::kJsonLimit);
  try {
    return json::parse(text);
  } catch (const json::exception& e) {
    // e.what() reads "[json.exception.parse_error.101] parse error at line 3, column 7: ...";
    // the bracketed id means nothing to a user.
    std::string what = e.what();
    if (const auto close = what.find("] "); what.starts_with("[json.") && close != std::string::npos)
      what.erase(0, close + 2);
    fail(file, "invalid JSON: " + what);
  }
}

const json& member(const std::filesystem::path& file, const json& object, const char* key, const std::string& field) {
  if (!object.is_object()) bad_field(file, field, std::string("the enclosing value is not an object"));
  const auto it = object.find(key);
  if (it == object.end()) bad_field(file, field, "missing");
  return *it;
}

namespace {
std::string format_number(double x) {
  std::ostringstream s;
  s << x;
  return s.str();
}
}  // namespace

double number_field(const std::filesystem::path& file, const json& j, const std::string& field, double lo, double hi,
                    const char* unit) {
  if (!j.is_number()) bad_field(file, field, std::string("expected a number, found ") + j.type_name());
  const double x = j.get<double>();
  if (!std::isfinite(x) || x < lo || x > hi)
    bad_field(file, field, "must be from " + format_number(lo) + " to " + format_number(hi) + " " + unit + ", found " + j.dump());
  return x;
}

Eigen::VectorXd number_array(const std::filesystem::path& file, const json& j, const std::string& field, int n) {
  if (!j.is_array() || j.size() != static_cast<std::size_t>(n))
    bad_field(file, field,
              "expected an array of " + std::to_string(n) + " numbers, found " +
                  (j.is_array() ? "an array of " + std::to_string(j.size()) + " items" : std::string(j.type_name())));
  Eigen::VectorXd v(n);
  for (int k = 0; k < n; ++k) {
    const json& x = j[static_cast<std::size_t>(k)];
    if (!x.is_number() || !std::isfinite(x.get<double>()))
      bad_field(file, field + "[" + std::to_string(k) + "]", "expected a finite number, found " + x.dump());
    v(k) = x.get<double>();
  }
  return v;
}

}  // namespace evar::geometry::detail
