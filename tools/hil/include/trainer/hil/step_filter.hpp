// `hil check --only PART/NAME`: which steps run. "can" = every step of the part;
// "can/heartbeat_loss" = the step of that name on every axis; "can/left.pitch" = every step of
// one axis; "can/left.pitch.heartbeat_loss" = one step; "can/bus" = the bus statistics.
// No entry = everything.
#pragma once

#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace trainer::hil {

class StepFilter {
 public:
  StepFilter() = default;
  explicit StepFilter(std::vector<std::string> only) : only_(std::move(only)) {}
  // `id` as in StepResult::id ("can.left.pitch.torque_limit").
  bool wants(std::string_view id) const;
  // Whether a step named one of `steps` under `prefix` ("can.left.pitch") is wanted.
  bool wants_any_under(std::string_view prefix, std::initializer_list<const char*> steps) const;
  // Whether any step of `part` ("can", "gpio", "usb") can be wanted.
  bool wants_part(std::string_view part) const;
  bool empty() const noexcept { return only_.empty(); }

 private:
  std::vector<std::string> only_;
};

}  // namespace trainer::hil
