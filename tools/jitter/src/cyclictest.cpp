#include "cyclictest.hpp"

#include <charconv>
#include <optional>

namespace trainer::tools::jitter {

namespace {

std::string_view trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t' || text.back() == '\r')) {
    text.remove_suffix(1);
  }
  return text;
}

// A whole decimal number, leading zeros allowed (cyclictest pads with them).
std::optional<std::uint64_t> parse_unsigned(std::string_view text) {
  text = trim(text);
  if (text.empty()) return std::nullopt;
  std::uint64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc{} || end != text.data() + text.size()) return std::nullopt;
  return value;
}

}  // namespace

LatencyDistribution CyclictestHistogram::distribution() const {
  std::vector<LatencyBin> bins;
  for (std::size_t k = 0; k < counts.size(); ++k) {
    if (counts[k] == 0) continue;
    const auto lower_ns = static_cast<std::int64_t>(k) * kNanosecondsPerMicrosecond;
    bins.push_back(LatencyBin{lower_ns, lower_ns + kNanosecondsPerMicrosecond, counts[k]});
  }
  const std::int64_t largest_ns = (max_us + 1) * kNanosecondsPerMicrosecond;
  if (overflows > 0) {
    bins.push_back(LatencyBin{limit_us() * kNanosecondsPerMicrosecond, largest_ns, overflows});
  }
  // parse_cyclictest_histogram checked what from_bins requires.
  auto distribution = LatencyDistribution::from_bins(std::move(bins), largest_ns);
  return distribution ? std::move(*distribution) : LatencyDistribution{};
}

core::Expected<CyclictestHistogram> parse_cyclictest_histogram(std::string_view text,
                                                               std::string_view source) {
  CyclictestHistogram histogram;
  std::optional<std::uint64_t> total;
  std::optional<std::uint64_t> min_us;
  std::optional<std::uint64_t> avg_us;
  std::optional<std::uint64_t> max_us;
  std::optional<std::uint64_t> overflows;
  std::size_t line_number = 0;
  const auto fail = [&](const std::string& what) {
    return core::make_error(std::string(source) + ":" + std::to_string(line_number) + ": " + what);
  };

  while (!text.empty()) {
    const std::size_t newline = text.find('\n');
    const std::string_view raw = text.substr(0, newline);
    text.remove_prefix(newline == std::string_view::npos ? text.size() : newline + 1);
    ++line_number;
    const std::string_view line = trim(raw);
    if (line.empty()) continue;

    if (line.front() == '#') {
      // "# Key: value" summary lines; other comment lines (the header, the overflow cycle
      // numbers, anything a later cyclictest adds) carry nothing the comparison needs.
      const std::string_view body = trim(line.substr(1));
      const std::size_t colon = body.find(':');
      if (colon == std::string_view::npos) continue;
      const std::string_view key = trim(body.substr(0, colon));
      std::optional<std::uint64_t>* field = nullptr;
      if (key == "Total") field = &total;
      if (key == "Min Latencies") field = &min_us;
      if (key == "Avg Latencies") field = &avg_us;
      if (key == "Max Latencies") field = &max_us;
      if (key == "Histogram Overflows") field = &overflows;
      if (field == nullptr) continue;
      const std::string_view value_text = trim(body.substr(colon + 1));
      const auto value = parse_unsigned(value_text);
      if (!value) {
        return fail("'# " + std::string(key) + ": " + std::string(value_text) +
                    "': expected one whole number (a histogram of one thread, cyclictest -t1)");
      }
      *field = value;
      continue;
    }

    // A bin: "<latency us> <count>".
    const std::size_t space = line.find_first_of(" \t");
    const auto latency = parse_unsigned(line.substr(0, space));
    const auto count =
        space == std::string_view::npos ? std::nullopt : parse_unsigned(line.substr(space + 1));
    if (!latency || !count) {
      // Appended piece by piece: GCC 12 at -O3 raises a false -Wrestrict on "literal" + string.
      std::string what = "'";
      what.append(line).append(
          "': expected a histogram line '<latency us> <count>' of one thread (cyclictest -t1), "
          "or a '#' comment");
      return fail(what);
    }
    if (*latency != histogram.counts.size()) {
      return fail("bin " + std::to_string(*latency) + ": expected bin " +
                  std::to_string(histogram.counts.size()) +
                  " (cyclictest lists every microsecond from 0, in order)");
    }
    histogram.counts.push_back(*count);
    histogram.in_range += *count;
  }

  ++line_number;  // errors below concern the file as a whole: name the end of it
  const auto missing = [&](std::string_view what) {
    return core::make_error(std::string(source) + ": no '# " + std::string(what) +
                            ":' line; expected cyclictest's histogram file (-h N --histfile=F)");
  };
  if (histogram.counts.empty()) {
    return core::make_error(std::string(source) +
                            ": no histogram lines; expected cyclictest's histogram file "
                            "(-h N --histfile=F)");
  }
  if (!total) return missing("Total");
  if (!min_us) return missing("Min Latencies");
  if (!avg_us) return missing("Avg Latencies");
  if (!max_us) return missing("Max Latencies");
  if (!overflows) return missing("Histogram Overflows");
  if (*total != histogram.in_range) {
    return core::make_error(std::string(source) + ": '# Total: " + std::to_string(*total) +
                            "' but the histogram lines add up to " +
                            std::to_string(histogram.in_range));
  }
  histogram.overflows = *overflows;
  histogram.min_us = static_cast<std::int64_t>(*min_us);
  histogram.avg_us = static_cast<std::int64_t>(*avg_us);
  histogram.max_us = static_cast<std::int64_t>(*max_us);
  if (histogram.samples() == 0) {
    return core::make_error(std::string(source) + ": no samples (Total and Overflows are 0)");
  }
  // Where the largest sample lies must agree with the bins: in the overflow when there is one,
  // else in the highest non-empty bin.
  std::size_t highest = histogram.counts.size();
  while (highest > 0 && histogram.counts[highest - 1] == 0) --highest;
  const bool max_consistent =
      histogram.overflows > 0
          ? histogram.max_us >= histogram.limit_us()
          : highest > 0 && static_cast<std::int64_t>(highest - 1) == histogram.max_us;
  if (!max_consistent) {
    return core::make_error(
        std::string(source) + ": '# Max Latencies: " + std::to_string(histogram.max_us) +
        "' disagrees with the bins (" + std::to_string(histogram.overflows) +
        " overflows, highest bin " +
        (highest > 0 ? std::to_string(highest - 1) : std::string("none")) + ")");
  }
  return histogram;
}

std::vector<std::string> cyclictest_arguments(const CyclictestSettings& settings) {
  std::vector<std::string> args{settings.executable, "-q", "-t1",
                                "-i" + std::to_string(settings.period_us)};
  if (settings.priority > 0) {
    args.push_back("--policy=fifo");
    args.push_back("-p" + std::to_string(settings.priority));
  } else {
    args.push_back("--policy=other");
    args.push_back("-p0");
  }
  if (settings.cpu >= 0) args.push_back("-a" + std::to_string(settings.cpu));
  if (settings.lock_memory) args.push_back("-m");
  // cyclictest holds /dev/cpu_dma_latency at 0 unless told otherwise; mirror the trainer.
  if (settings.cpu_dma_latency_us >= 0) {
    args.push_back("--latency=" + std::to_string(settings.cpu_dma_latency_us));
  } else {
    args.push_back("--laptop");
  }
  if (settings.loops > 0) args.push_back("-l" + std::to_string(settings.loops));
  args.push_back("-h" + std::to_string(settings.histogram_limit_us));
  args.push_back("--histfile=" + settings.histogram_file);
  return args;
}

}  // namespace trainer::tools::jitter
