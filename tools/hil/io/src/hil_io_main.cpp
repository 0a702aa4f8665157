// hil_io: the test driver of hil's GPIO and USB parts until they are registered in `hil`
// (docs/hil-io.md). Loads the device file, runs the parts' scan or check, prints one line per
// item/step (or the sections as JSON) and exits 1 when any step failed.
//
//   hil_io scan|check [--device FILE] [--part gpio|usb|all] [--yes] [--act CMD] [--json]
//                     [--slow-motion N] [--trials N] [--action-timeout S] [--period-ms X]
//                     [--latch-margin-ms X] [--exchanges N]
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <string>

#include <CLI/CLI.hpp>

#include "trainer/config/device.hpp"
#include "trainer/hil/io_parts.hpp"

namespace {

// The person at the bench, at a terminal; or a script (--act CMD: each action runs
// `CMD ACTION` and has happened when it returns); --yes answers every question with yes.
class DriverOperator final : public trainer::hil::Operator {
 public:
  DriverOperator(bool yes, std::string act) : yes_(yes), act_(std::move(act)) {}

  bool request(std::string_view action, std::string_view instruction) override {
    if (!act_.empty()) {
      const pid_t pid = fork();
      if (pid < 0) return false;
      if (pid == 0) {
        const std::string command = act_ + " " + std::string(action);
        execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
        _exit(127);
      }
      int status = 0;
      while (waitpid(pid, &status, 0) < 0) {
      }
      if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        std::cerr << "hil_io: '" << act_ << " " << action << "' failed (status " << status
                  << "): taken as declined\n";
        return false;
      }
      return true;
    }
    std::cerr << "[" << action << "] " << instruction;
    if (yes_) {
      std::cerr << " (now)\n";
      return true;
    }
    std::cerr << " — press Enter when ready, or n + Enter to skip: ";
    std::string answer;
    if (!std::getline(std::cin, answer)) return false;
    return answer != "n" && answer != "N";
  }

  bool confirm(std::string_view question) override {
    std::cerr << question;
    if (yes_) {
      std::cerr << " yes (--yes)\n";
      return true;
    }
    std::cerr << " [y/N] ";
    std::string answer;
    if (!std::getline(std::cin, answer)) return false;
    return answer == "y" || answer == "Y" || answer == "yes";
  }

 private:
  bool yes_;
  std::string act_;
};

struct Tally {
  int pass = 0, fail = 0, skip = 0;
};

bool any_failed(const std::vector<trainer::hil::StepResult>& steps, Tally& tally) {
  bool failed = false;
  for (const auto& step : steps) {
    switch (step.outcome) {
      case trainer::hil::Outcome::pass: ++tally.pass; break;
      case trainer::hil::Outcome::fail: ++tally.fail; failed = true; break;
      case trainer::hil::Outcome::skip: ++tally.skip; break;
    }
  }
  return failed;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hil_io: the GPIO and USB parts of the hil bring-up tool (test driver, docs/hil-io.md)"};
  app.require_subcommand(1);
  std::string device_file;
  std::string part = "all";
  bool yes = false;
  std::string act;
  bool json = false;
  std::int64_t slow_motion = 1;
  int trials = 0;
  double action_timeout = 10.0;
  double period_ms = 0.0;
  std::int64_t exchanges = 1000;
  double latch_margin_ms = -1.0;
  auto add_common = [&](CLI::App* sub) {
    sub->add_option("--device", device_file, "device file (config/devices/*.toml)");
    sub->add_option("--part", part, "gpio, usb or all")->check(CLI::IsMember({"gpio", "usb", "all"}));
    sub->add_flag("--yes", yes, "answer every question with yes");
    sub->add_option("--act", act, "run CMD ACTION for every operator action (scripted bench)");
    sub->add_flag("--json", json, "print the sections as JSON");
    sub->add_option("--slow-motion", slow_motion, "time stretch of an emulated bench")
        ->check(CLI::Range(1, 1000));
    sub->add_option("--trials", trials, "repeats of timed steps (0 = each step's default)")
        ->check(CLI::Range(0, 100000));
    sub->add_option("--action-timeout", action_timeout, "seconds a step waits for an action")
        ->check(CLI::Range(0.1, 3600.0));
    sub->add_option("--period-ms", period_ms,
                    "read period of the GPIO check (default 1 ms x slow motion)")
        ->check(CLI::Range(0.0, 1000.0));
    sub->add_option("--latch-margin-ms", latch_margin_ms,
                    "edge-to-latch limit = period + this (default half a period)")
        ->check(CLI::Range(0.0, 10000.0));
    sub->add_option("--exchanges", exchanges, "USB round-trip exchanges (default 1000)")
        ->check(CLI::Range(std::int64_t{10}, std::int64_t{10'000'000}));
  };
  CLI::App* scan = app.add_subcommand("scan", "what is on the bench, compared with the device file");
  CLI::App* check = app.add_subcommand("check", "the GPIO and USB check steps");
  add_common(scan);
  add_common(check);
  CLI11_PARSE(app, argc, argv);

  DriverOperator op(yes, act);
  trainer::hil::BenchContext bench;
  bench.op = &op;
  bench.slow_motion = slow_motion;
  bench.trials = trials;
  bench.action_timeout_s = action_timeout;
  if (!device_file.empty()) {
    auto loaded = trainer::config::load_device(device_file);
    if (!loaded) {
      std::cerr << "hil_io: " << loaded.error().message << "\n";
      return 2;
    }
    bench.device = std::move(*loaded);
  }
  const bool gpio = part == "gpio" || part == "all";
  const bool usb = part == "usb" || part == "all";
  nlohmann::json out = nlohmann::json::array();
  bool failed = false;
  Tally tally;
  if (scan->parsed()) {
    std::vector<trainer::hil::ScanSection> sections;
    if (gpio) sections.push_back(trainer::hil::scan_gpio(bench));
    if (usb) sections.push_back(trainer::hil::scan_usb(bench));
    for (const auto& s : sections) {
      failed = any_failed(s.comparison, tally) || failed;
      if (json) {
        out.push_back(trainer::hil::to_json(s));
      } else {
        std::cout << trainer::hil::format_scan(s) << std::flush;
      }
    }
  } else {
    trainer::hil::GpioCheckOptions options;
    options.period_ns = static_cast<std::int64_t>(period_ms * 1e6);
    if (latch_margin_ms >= 0.0) options.margin_ns = static_cast<std::int64_t>(latch_margin_ms * 1e6);
    trainer::hil::UsbCheckOptions usb_options;
    usb_options.exchanges = exchanges;
    std::vector<trainer::hil::CheckSection> sections;
    if (gpio) sections.push_back(trainer::hil::check_gpio(bench, options));
    if (usb) sections.push_back(trainer::hil::check_usb(bench, usb_options));
    for (const auto& s : sections) {
      failed = any_failed(s.steps, tally) || failed;
      if (json) {
        out.push_back(trainer::hil::to_json(s));
      } else {
        std::cout << trainer::hil::format_check(s) << std::flush;
      }
    }
  }
  if (json) {
    std::cout << out.dump(2) << "\n";
  } else {
    std::cout << tally.pass << " passed, " << tally.fail << " failed, " << tally.skip
              << " skipped\n";
  }
  return failed ? 1 : 0;
}
