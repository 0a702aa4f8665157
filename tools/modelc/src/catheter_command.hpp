// `modelc catheter-static`: the particle catheter clamped along +x at the origin, settled to
// static equilibrium under a tip force of fixed direction (large deflections included).
#pragma once

#include <CLI/CLI.hpp>

namespace trainer::tools::modelc {

void add_catheter_static_command(CLI::App& app, int& exit_code);

}  // namespace trainer::tools::modelc
