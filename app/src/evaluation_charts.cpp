#include "evaluation_charts.hpp"

#include <plplot/plstream.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace evar::app {
namespace {

// The seed paper's Table 1, Euclidean means (mm).
constexpr double kPaperInitialMm = 19.81, kPaperAdaptedMm = 4.56;

enum Colour { kBlack = 1, kInitial, kAdapted, kPaper, kGrid };

// One PNG page of `panels` charts stacked vertically; PLplot writes the file when the
// stream ends (finish(), or the destructor on an error path).
class Page {
 public:
  Page(const std::filesystem::path& path, int panels) : path_(path) {
    // Without its driver PLplot would ask on the terminal for another device and then exit
    // the process: look for it first.
    int count = 0;
    std::vector<const char*> menu(256), names(256);
    count = static_cast<int>(names.size());
    const char** menu_out = menu.data();
    const char** names_out = names.data();
    plgDevs(&menu_out, &names_out, &count);
    bool have = false;
    for (int i = 0; i < count; ++i) have = have || std::string(names_out[i]) == "pngcairo";
    if (!have)
      throw std::runtime_error(path_.string() + ": cannot draw it: PLplot has no pngcairo device (install plplot-driver-cairo)");
    std::filesystem::remove(path_);
    plstream& pls = pls_.emplace();
    pls.sdev("pngcairo");
    pls.sfnam(path_.string().c_str());
    pls.spage(0, 0, 1200, 60 + 380 * std::max(1, panels), 0, 0);
    pls.scolbg(255, 255, 255);
    pls.scol0(kBlack, 40, 40, 40);
    pls.scol0(kInitial, 120, 150, 175);
    pls.scol0(kAdapted, 240, 140, 40);
    pls.scol0(kPaper, 190, 40, 40);
    pls.scol0(kGrid, 215, 215, 215);
    pls.ssub(1, std::max(1, panels));
    pls.init();
    pls.schr(0.0, 0.85);
  }
  plstream& operator*() { return *pls_; }
  plstream* operator->() { return &*pls_; }
  /// Ends the stream and checks that the file is there.
  void finish() {
    pls_.reset();
    if (!std::filesystem::is_regular_file(path_) || std::filesystem::file_size(path_) == 0)
      throw std::runtime_error(path_.string() + ": cannot write (PLplot's pngcairo device wrote nothing)");
  }

 private:
  std::filesystem::path path_;
  std::optional<plstream> pls_;
};

struct Pair {
  double initial = 0.0, adapted = 0.0;
};

// Per group ("beam physics, paper difficulty"), per session in order: the protocol's
// ostia (on an iliac carrying the device) averaged, or none.
std::map<std::string, std::vector<std::pair<std::size_t, Pair>>> protocol_by_group(const std::vector<CaseEvaluation>& cases) {
  std::map<std::string, std::vector<std::pair<std::size_t, Pair>>> groups;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    const CaseEvaluation& c = cases[i];
    Pair p;
    int n = 0;
    for (const auto& l : c.landmarks)
      if (l.on_device_vessel) {
        p.initial += l.initial_mm;
        p.adapted += l.adapted_mm;
        ++n;
      }
    const std::string group = c.physics == "unknown" ? "sessions" : c.physics + " physics, " + c.difficulty + " difficulty";
    auto& rows = groups[group];
    if (n > 0) rows.push_back({i + 1, {p.initial / n, p.adapted / n}});
  }
  return groups;
}

std::string mm(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

// The paper's means as dashed lines across the frame (horizontal, or vertical for a
// distribution); their values are in the legend, so nothing is written over the bars.
void paper_lines(plstream& pls, double x0, double x1, bool vertical, double y_top) {
  pls.col0(kPaper);
  pls.lsty(2);
  for (const double v : {kPaperInitialMm, kPaperAdaptedMm}) {
    PLFLT x[2] = {x0, x1}, y[2] = {v, v};
    if (vertical) x[0] = x[1] = v, y[0] = 0.0, y[1] = y_top;
    pls.line(2, x, y);
  }
  pls.lsty(1);
}

std::string sessions_text(std::size_t n) { return std::to_string(n) + (n == 1 ? " session" : " sessions"); }

// What the adapted models were bent from: moved with the pelvis found in the bones (the
// node's default), or where the registration put them (`eval --no-pelvis`, or scenes
// without the pelvis's bones), so that two runs' charts are not taken for one another.
std::string adapted_label(const std::vector<CaseEvaluation>& cases) {
  const bool pelvis = std::any_of(cases.begin(), cases.end(), [](const CaseEvaluation& c) { return c.pelvis.has_value(); });
  return pelvis ? "adapted, pelvis found" : "adapted, as registered";
}

// The legend in the top margin: each series' name in its colour.
void legend(plstream& pls, const std::string& adapted) {
  pls.col0(kInitial);
  pls.mtex("t", 0.8, 0.0, 0.0, "initial (preoperative)");
  pls.col0(kAdapted);
  pls.mtex("t", 0.8, 0.20, 0.0, adapted.c_str());
  pls.col0(kPaper);
  pls.mtex("t", 0.8, 0.42, 0.0, ("- - - the paper's Table 1 means: initial " + mm(kPaperInitialMm) + " mm, adapted " +
                                 mm(kPaperAdaptedMm) + " mm").c_str());
  pls.col0(kBlack);
}

void bar(plstream& pls, double x0, double x1, double height, Colour colour) {
  PLFLT x[4] = {x0, x0, x1, x1}, y[4] = {0.0, height, height, 0.0};
  pls.col0(colour);
  pls.fill(4, x, y);
}

double mean(const std::vector<std::pair<std::size_t, Pair>>& rows, double Pair::*m) {
  double s = 0.0;
  for (const auto& [i, p] : rows) s += p.*m;
  return rows.empty() ? 0.0 : s / static_cast<double>(rows.size());
}

}  // namespace

void write_per_case_chart(const std::filesystem::path& path, const std::vector<CaseEvaluation>& cases) {
  const auto groups = protocol_by_group(cases);
  Page page(path, static_cast<int>(groups.size()));
  for (const auto& [name, rows] : groups) {
    page->adv(0);
    double top = kPaperInitialMm;
    for (const auto& [i, p] : rows) top = std::max({top, p.initial, p.adapted});
    top = 1.15 * top;
    // Bars at the session's place among all sessions given (its number in eval.json's cases).
    const double first = rows.empty() ? 1.0 : static_cast<double>(rows.front().first);
    const double last = rows.empty() ? 1.0 : static_cast<double>(rows.back().first);
    page->vpor(0.07, 0.97, 0.14, 0.82);
    page->wind(first - 0.6, last + 0.6, 0.0, top);
    page->col0(kGrid);
    page->box("", 0.0, 0, "g", 0.0, 0);
    for (const auto& [index, pair] : rows) {
      const double x = static_cast<double>(index);
      bar(*page, x - 0.36, x, pair.initial, kInitial);
      bar(*page, x, x + 0.36, pair.adapted, kAdapted);
    }
    paper_lines(*page, first - 0.6, last + 0.6, false, top);
    page->col0(kBlack);
    page->box("bcnst", last - first < 15.0 ? 1.0 : 5.0, 1, "bcnstv", 0.0, 0);
    page->lab("session (its number among those given to eval)", "distance at the isocenter (mm)", "");
    const std::string title = name + ": internal iliac ostium of the iliac carrying the device, " +
                              sessions_text(rows.size()) + ", mean " + mm(mean(rows, &Pair::initial)) +
                              " -> " + mm(mean(rows, &Pair::adapted)) + " mm";
    page->mtex("t", 2.4, 0.5, 0.5, title.c_str());
    legend(*page, adapted_label(cases));
  }
  page.finish();
}

void write_distribution_chart(const std::filesystem::path& path, const std::vector<CaseEvaluation>& cases) {
  const auto groups = protocol_by_group(cases);
  Page page(path, static_cast<int>(groups.size()));
  constexpr double kBinMm = 2.0;
  for (const auto& [name, rows] : groups) {
    page->adv(0);
    double right = kPaperInitialMm + 5.0;
    for (const auto& [i, p] : rows) right = std::max({right, p.initial + kBinMm, p.adapted + kBinMm});
    const auto bins = static_cast<std::size_t>(std::ceil(right / kBinMm));
    std::vector<double> initial(bins, 0.0), adapted(bins, 0.0);
    for (const auto& [i, p] : rows) {
      initial[std::min(bins - 1, static_cast<std::size_t>(p.initial / kBinMm))] += 1.0;
      adapted[std::min(bins - 1, static_cast<std::size_t>(p.adapted / kBinMm))] += 1.0;
    }
    const double top = 1.25 * std::max(1.0, std::max(*std::max_element(initial.begin(), initial.end()),
                                                     *std::max_element(adapted.begin(), adapted.end())));
    page->vpor(0.07, 0.97, 0.14, 0.82);
    page->wind(0.0, static_cast<double>(bins) * kBinMm, 0.0, top);
    page->col0(kGrid);
    page->box("", 0.0, 0, "g", 0.0, 0);
    for (std::size_t b = 0; b < bins; ++b) {
      const double x = static_cast<double>(b) * kBinMm;
      if (initial[b] > 0) bar(*page, x + 0.1, x + 0.5 * kBinMm, initial[b], kInitial);
      if (adapted[b] > 0) bar(*page, x + 0.5 * kBinMm, x + kBinMm - 0.1, adapted[b], kAdapted);
    }
    paper_lines(*page, 0.0, static_cast<double>(bins) * kBinMm, true, top);
    page->col0(kBlack);
    page->box("bcnst", 0.0, 0, "bcnstv", top <= 12.0 ? 1.0 : 0.0, top <= 12.0 ? 1 : 0);  // whole sessions
    page->lab("distance at the isocenter (mm), 2 mm bins", "sessions", "");
    page->mtex("t", 2.4, 0.5, 0.5, (name + ": internal iliac ostium of the iliac carrying the device, " +
                                    sessions_text(rows.size())).c_str());
    legend(*page, adapted_label(cases));
  }
  page.finish();
}

}  // namespace evar::app
