#include "jitter_plot.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "child_process.hpp"

namespace trainer::tools::jitter {

namespace {

void append_density(std::string& out, const LatencyDistribution& distribution) {
  char line[96];
  for (const LatencyBin& bin : distribution.bins()) {
    const double width_us = to_us(bin.upper_ns - bin.lower_ns);
    std::snprintf(line, sizeof line, "%.4f %.6g\n",
                  0.5 * (to_us(bin.lower_ns) + to_us(bin.upper_ns)),
                  static_cast<double>(bin.count) / width_us);
    out += line;
  }
}

void append_ccdf(std::string& out, const LatencyDistribution& distribution) {
  if (distribution.count() == 0) return;
  char line[96];
  const auto total = static_cast<double>(distribution.count());
  std::uint64_t at_or_above = distribution.count();
  for (const LatencyBin& bin : distribution.bins()) {
    // A log axis cannot show 0: cyclictest's [0, 1) µs bin is drawn from 0.5 µs.
    const double x_us = bin.lower_ns > 0 ? to_us(bin.lower_ns) : 0.5 * to_us(bin.upper_ns);
    std::snprintf(line, sizeof line, "%.4f %.6g\n", x_us, static_cast<double>(at_or_above) / total);
    out += line;
    at_or_above -= bin.count;
  }
  // Close the last step at the largest sample.
  std::snprintf(line, sizeof line, "%.4f %.6g\n", to_us(distribution.largest_ns()),
                static_cast<double>(distribution.bins().back().count) / total);
  out += line;
}

// gnuplot string literal in double quotes.
std::string quoted(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

std::string plot_data(const LatencyDistribution& trainer, const LatencyDistribution& cyclictest) {
  std::string out = "# jitter plot data: four data sets, two blank lines apart\n";
  out += "# index 0: trainer wake-up latency density: bin centre (us), samples per us\n";
  append_density(out, trainer);
  out += "\n\n# index 1: cyclictest latency density: bin centre (us), samples per us\n";
  append_density(out, cyclictest);
  out += "\n\n# index 2: trainer: bin lower edge (us), fraction of wake-ups in that bin or above\n";
  append_ccdf(out, trainer);
  out +=
      "\n\n# index 3: cyclictest: bin lower edge (us), fraction of wake-ups in that bin or above\n";
  append_ccdf(out, cyclictest);
  return out;
}

std::string plot_script(const LatencyDistribution& trainer, const LatencyDistribution& cyclictest,
                        const PlotLabels& labels) {
  // One x range for both panels, from the lowest to the highest sample of either side.
  double low_us = 1e9;
  double high_us = 1.0;
  std::uint64_t most_samples = 1;
  for (const LatencyDistribution* distribution : {&trainer, &cyclictest}) {
    if (distribution->count() == 0) continue;
    const LatencyBin& first = distribution->bins().front();
    low_us =
        std::min(low_us, first.lower_ns > 0 ? to_us(first.lower_ns) : 0.5 * to_us(first.upper_ns));
    high_us = std::max(high_us, to_us(distribution->largest_ns()));
    most_samples = std::max(most_samples, distribution->count());
  }
  if (low_us > high_us) low_us = 0.5 * high_us;
  std::ostringstream gp;
  gp << "# Written by jitter; redraw with `gnuplot jitter.gp` in this directory.\n"
     << "set encoding utf8\n"
     << "set terminal pngcairo noenhanced size 1100,1000 font \",11\"\n"
     << "set output 'jitter.png'\n"
     << "set multiplot layout 2,1 title " << quoted(labels.title) << "\n"
     << "set logscale xy\n"
     << "set format x \"%g\"\n"
     << "set format y \"%g\"\n"
     << "set grid xtics ytics mxtics\n"
     << "set xrange [" << low_us * 0.8 << ":" << high_us * 1.25 << "]\n"
     << "set xlabel \"wake-up latency (µs)\"\n"
     << "set key top right\n"
     << "set ylabel \"samples per µs\"\n"
     << "plot 'jitter_plot.dat' index 0 using 1:2 with points pt 7 ps 0.5 lc rgb '#d62728' title "
     << quoted(labels.trainer_key) << ", \\\n"
     << "     'jitter_plot.dat' index 1 using 1:2 with points pt 5 ps 0.5 lc rgb '#1f77b4' title "
     << quoted(labels.cyclictest_key) << "\n"
     << "set ylabel \"fraction of wake-ups at or above\"\n"
     << "set yrange [" << 0.5 / static_cast<double>(most_samples) << ":1.5]\n"
     << "plot 'jitter_plot.dat' index 2 using 1:2 with steps lw 2 lc rgb '#d62728' title "
     << quoted(labels.trainer_key) << ", \\\n"
     << "     'jitter_plot.dat' index 3 using 1:2 with steps lw 2 lc rgb '#1f77b4' title "
     << quoted(labels.cyclictest_key) << ", \\\n"
     << "     0.01 with lines dt 2 lc rgb 'gray40' title \"p99\", \\\n"
     << "     0.001 with lines dt 3 lc rgb 'gray40' title \"p99.9\"\n"
     << "unset multiplot\n";
  return gp.str();
}

core::Expected<void> run_gnuplot(const std::string& gnuplot, const std::filesystem::path& out_dir) {
  if (!find_executable(gnuplot)) {
    return core::make_error("gnuplot ('" + gnuplot +
                            "') not found: install Debian's gnuplot-nox (tools/install-deps.sh); "
                            "the data and jitter.gp are written, run `gnuplot jitter.gp` in " +
                            out_dir.string() + " later");
  }
  const std::filesystem::path directory = std::filesystem::absolute(out_dir);
  const std::filesystem::path output = directory / "gnuplot_output.txt";
  std::error_code ignored;
  std::filesystem::remove(directory / "jitter.png", ignored);  // never leave an earlier run's
  auto child = ChildProcess::start({gnuplot, "jitter.gp"}, output, directory);
  if (!child) return std::move(child).error();
  const int status = child->wait();
  std::ifstream in(output);
  std::stringstream text;
  text << in.rdbuf();
  if (status != 0) {
    return core::make_error("gnuplot failed with status " + std::to_string(status) + ": " +
                            text.str());
  }
  if (!std::filesystem::exists(directory / "jitter.png")) {
    return core::make_error("gnuplot ran but wrote no jitter.png: " + text.str());
  }
  return {};
}

}  // namespace trainer::tools::jitter
