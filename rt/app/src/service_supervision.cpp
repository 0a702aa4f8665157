#include "trainer/app/service_supervision.hpp"

#include <cstdio>
#include <utility>

#include "trainer/safety/safety_supervisor.hpp"

namespace trainer::app {

ServiceSupervision::ServiceSupervision(bool arm, std::string scene_name, std::int64_t period_ns)
    : notifier_(appliance::ServiceNotifier::from_environment()),
      watchdog_(notifier_.watchdog_usec()),
      arm_(arm),
      scene_name_(std::move(scene_name)),
      rate_hz_(period_ns > 0 ? 1e9 / static_cast<double>(period_ns) : 0.0) {}

void ServiceSupervision::observe(const TelemetrySnapshot& snapshot) noexcept {
  cycle_ = snapshot.cycle;
  latched_faults_ = snapshot.latched_faults;
}

void ServiceSupervision::tick(bool finished, std::int64_t now_ns) {
  if (!notifier_.active()) return;
  if (!ready_) {
    if (cycle_ == 0 || finished) return;
    if (arm_ && latched_faults_ != 0) {
      if (latched_faults_ != waiting_faults_) {
        waiting_faults_ = latched_faults_;
        char text[64];
        std::snprintf(text, sizeof text, "waiting to arm: latched faults 0x%x", latched_faults_);
        notifier_.status(text);
      }
      return;
    }
    ready_ = true;
    char text[160];
    std::snprintf(text, sizeof text, "%s scene %s: loop at %.0f Hz",
                  arm_ ? "armed" : "running unarmed", scene_name_.c_str(), rate_hz_);
    notifier_.ready(text);
  }
  const bool overrun = (latched_faults_ & safety::bit(safety::Fault::overrun_streak)) != 0;
  if (watchdog_.should_ping(now_ns, {cycle_, overrun, finished})) notifier_.watchdog();
  if (watchdog_.health() != reported_health_ &&
      watchdog_.health() != appliance::LoopHealth::not_started) {
    reported_health_ = watchdog_.health();
    notifier_.status("loop " + std::string(appliance::to_string(reported_health_)) +
                     (reported_health_ == appliance::LoopHealth::healthy
                          ? ""
                          : ": watchdog pings stopped at cycle " + std::to_string(cycle_)));
  }
}

void ServiceSupervision::stopping(bool by_signal) const {
  notifier_.stopping(by_signal ? "stopping: signal received" : "stopping: run ended");
}

}  // namespace trainer::app
