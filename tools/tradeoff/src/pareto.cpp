#include "pareto.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>

namespace trainer::tools::tradeoff {

std::vector<std::size_t> pareto_front(const std::vector<TradePoint>& points) {
  std::vector<std::size_t> order(points.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (points[a].cost_ns != points[b].cost_ns) return points[a].cost_ns < points[b].cost_ns;
    return points[a].error < points[b].error;
  });
  std::vector<std::size_t> front;
  for (std::size_t index : order) {
    // Cheapest first: a point joins the front when it is more accurate than every cheaper one.
    if (front.empty() || points[index].error < points[front.back()].error) front.push_back(index);
  }
  return front;
}

namespace {

// gnuplot cannot put 0 on a log axis: an error below 1e-6 % is drawn at 1e-6 %.
double plotted_error_percent(double error) { return std::max(100.0 * error, 1e-6); }

std::string quoted(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

std::string plot_pareto(const std::filesystem::path& directory, const std::string& stem,
                        const std::string& title, const std::string& error_label,
                        const std::vector<TradePoint>& points) {
  std::map<std::string, std::vector<std::size_t>> groups;
  std::vector<std::string> group_order;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!groups.contains(points[i].group)) group_order.push_back(points[i].group);
    groups[points[i].group].push_back(i);
  }
  std::vector<std::filesystem::path> group_files;
  for (std::size_t g = 0; g < group_order.size(); ++g) {
    const auto file = directory / (stem + "_group" + std::to_string(g) + ".dat");
    std::ofstream out(file);
    out << "# error_percent cost_us label\n";
    for (std::size_t i : groups[group_order[g]]) {
      out << plotted_error_percent(points[i].error) << ' ' << points[i].cost_ns / 1e3 << ' '
          << quoted(points[i].label) << '\n';
    }
    group_files.push_back(file);
  }
  const auto front_file = directory / (stem + "_front.dat");
  {
    std::ofstream out(front_file);
    out << "# error_percent cost_us label (Pareto front, cheapest first)\n";
    for (std::size_t i : pareto_front(points)) {
      out << plotted_error_percent(points[i].error) << ' ' << points[i].cost_ns / 1e3 << ' '
          << quoted(points[i].label) << '\n';
    }
  }
  const auto script = directory / (stem + ".gp");
  const auto png = directory / (stem + ".png");
  {
    std::ofstream out(script);
    out << "set terminal pngcairo size 1100,750 font 'sans,10'\n"
        << "set output " << quoted(png.string()) << "\n"
        << "set title " << quoted(title) << "\n"
        << "set logscale xy\nset grid xtics ytics mxtics mytics\n"
        << "set xlabel " << quoted(error_label) << "\nset format x '%g'\n"
        << "set ylabel 'median cost per 1 ms of simulated time (us)'\nset key outside right top\n"
        << "plot ";
    const char* markers[] = {"7", "5", "9", "11", "13", "3"};
    for (std::size_t g = 0; g < group_files.size(); ++g) {
      out << quoted(group_files[g].string()) << " using 1:2 with points pt " << markers[g % 6]
          << " ps 1.3 title " << quoted(group_order[g]) << ", ";
    }
    out << quoted(front_file.string())
        << " using 1:2 with lines lw 2 lc rgb 'black' title 'Pareto front', "
        << quoted(front_file.string())
        << " using 1:2:3 with labels left offset 0.8,0.4 font 'sans,8' notitle\n";
  }
  const std::string command = "gnuplot " + quoted(script.string()) + " 2>&1";
  const int status = std::system(command.c_str());
  if (status != 0) {
    return "gnuplot failed (exit status " + std::to_string(status) +
           "): is gnuplot-nox installed (tools/install-deps.sh)? Data and script are in " +
           directory.string();
  }
  return "";
}

}  // namespace trainer::tools::tradeoff
