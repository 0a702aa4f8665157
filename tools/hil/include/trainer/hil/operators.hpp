// The people (or scripts) at the bench: hil::Operator implementations of the program's options.
//  - ConsoleOperator: prints the instruction and waits for Enter on the terminal ("s" skips);
//    confirm() asks y/N. With `yes`, confirm() answers yes without asking.
//  - with `act_command` (the program's --act CMD): request(action, ...) runs `CMD action`
//    through /bin/sh and succeeds when it exits 0 (the bench VM moves simulated joints this
//    way); confirm() still needs --yes or a terminal.
// Without a terminal, --act or --yes every request is declined (the step is skipped, with why)
// and every confirm answered no.
//
// Interruption: install_interrupt_handler() makes SIGINT/SIGTERM set a flag that every timed
// loop of the parts checks (interrupted()); they then throw Interrupted, and the parts' guards
// take the torque off on the way out.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

#include "trainer/hil/step.hpp"

namespace trainer::hil {

struct OperatorOptions {
  bool yes = false;
  std::string act_command;  // "" = none
  bool interactive = true;  // stdin is a terminal
};

class ConsoleOperator final : public Operator {
 public:
  explicit ConsoleOperator(OperatorOptions options) : options_(std::move(options)) {}
  bool request(std::string_view action, std::string_view instruction) override;
  bool confirm(std::string_view question) override;

 private:
  OperatorOptions options_;
};

class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted (SIGINT/SIGTERM): torque removed, stopping") {}
};

void install_interrupt_handler();
bool interrupted() noexcept;
void set_interrupted(bool value) noexcept;  // tests
// Throws Interrupted when the flag is set.
void throw_if_interrupted();

}  // namespace trainer::hil
