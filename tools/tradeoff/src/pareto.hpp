// Pareto front of (cost, error) points and its plot: the part of the tradeoff tool that does not
// depend on any model. A point is on the front when no other point is both cheaper (or equal)
// and more accurate (or equal) with one of the two strictly better.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace trainer::tools::tradeoff {

struct TradePoint {
  std::string group;  // which knob was swept, e.g. "modes x static correction"
  std::string label;  // the configuration, e.g. "r40 sc dkt f32 dt1000us"
  double error = 0.0;    // fraction (0.02 = 2 %)
  double cost_ns = 0.0;  // median cost per cycle
};

// Indices of the points on the front, cheapest first.
std::vector<std::size_t> pareto_front(const std::vector<TradePoint>& points);

// Writes `<stem>.dat` files per group and the front, and `<stem>.gp`, then runs gnuplot to make
// `<stem>.png` (error in % on a log x axis, described by `error_label`, cost in µs on a log y axis, the front joined and
// labelled). Returns "" on success, else why the PNG was not made (the data files are written
// either way).
std::string plot_pareto(const std::filesystem::path& directory, const std::string& stem,
                        const std::string& title, const std::string& error_label,
                        const std::vector<TradePoint>& points);

}  // namespace trainer::tools::tradeoff
