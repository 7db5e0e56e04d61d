#pragma once
// Numbers in messages as people write them: "3 mm", "2.5 mm", "0.05 mm", not
// "3.000000 mm".
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

namespace evar::base {

/// `value` with at most `decimals` decimals, trailing zeros (and a bare point) dropped,
/// then a space and `unit` unless it is empty. Non-finite values print as "inf" / "nan".
inline std::string quantity_text(double value, std::string_view unit, int decimals = 2) {
  char text[64];
  if (!std::isfinite(value)) {
    std::snprintf(text, sizeof text, "%s", std::isnan(value) ? "nan" : (value > 0 ? "inf" : "-inf"));
  } else {
    std::snprintf(text, sizeof text, "%.*f", decimals < 0 ? 0 : decimals, value);
    std::string_view s(text);
    if (s.find('.') != std::string_view::npos) {
      std::size_t end = s.size();
      while (end > 0 && s[end - 1] == '0') --end;
      if (end > 0 && s[end - 1] == '.') --end;
      text[end] = '\0';
    }
    if (std::string_view(text) == "-0") text[0] = '0', text[1] = '\0';
  }
  std::string out = text;
  if (!unit.empty()) out.append(" ").append(unit);
  return out;
}

}  // namespace evar::base
