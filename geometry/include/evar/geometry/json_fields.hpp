#pragma once
// Reading JSON files field by field with errors of the form "<file>: <field>: <what>",
// shared by every reader of a JSON input (scene, markups, view geometry, node.json, the
// ARAP constraints), so each rejects bad input with an InputError naming the file.
#include <Eigen/Core>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace evar::geometry::detail {

[[noreturn]] void bad_field(const std::filesystem::path& file, const std::string& field, const std::string& what);

/// The whole file parsed; InputError with nlohmann's position text when it is not JSON.
nlohmann::json parse_json_file(const std::filesystem::path& file);

/// object[key], or InputError "<field>: missing".
const nlohmann::json& member(const std::filesystem::path& file, const nlohmann::json& object, const char* key,
                             const std::string& field);

/// A finite number in [lo, hi]; the message names the range and the unit.
double number_field(const std::filesystem::path& file, const nlohmann::json& j, const std::string& field, double lo,
                    double hi, const char* unit);

/// An array of exactly `n` finite numbers.
Eigen::VectorXd number_array(const std::filesystem::path& file, const nlohmann::json& j, const std::string& field,
                             int n);

}  // namespace evar::geometry::detail
