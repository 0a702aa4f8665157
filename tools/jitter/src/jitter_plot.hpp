// The picture of a jitter measurement: both wake-up latency distributions on log axes, drawn by
// gnuplot (pngcairo). Top panel: density (samples per µs, so the trainer's variable-width bins
// and cyclictest's 1 µs bins compare); bottom panel: the fraction of wake-ups at or above each
// latency (complementary CDF), where p99 and p99.9 are the crossings of 1e-2 and 1e-3. The
// tool writes the data (jitter_plot.dat) and the script (jitter.gp) and runs
// `gnuplot jitter.gp` in the output directory, so the plot can be redrawn by hand.
#pragma once

#include <filesystem>
#include <string>

#include "latency_distribution.hpp"
#include "trainer/core/expected.hpp"

namespace trainer::tools::jitter {

// Four gnuplot data sets separated by two blank lines: index 0/1 the trainer's/cyclictest's
// density (bin centre µs, samples per µs), index 2/3 their complementary CDF (bin lower
// edge µs, fraction of samples in that bin or above; a last point at the largest sample).
std::string plot_data(const LatencyDistribution& trainer, const LatencyDistribution& cyclictest);

struct PlotLabels {
  std::string title;
  std::string trainer_key;
  std::string cyclictest_key;
};

std::string plot_script(const LatencyDistribution& trainer, const LatencyDistribution& cyclictest,
                        const PlotLabels& labels);

// Runs `gnuplot jitter.gp` in out_dir (output in gnuplot_output.txt there). The error says
// whether gnuplot is missing (with the package to install) or failed (with its output).
core::Expected<void> run_gnuplot(const std::string& gnuplot, const std::filesystem::path& out_dir);

}  // namespace trainer::tools::jitter
