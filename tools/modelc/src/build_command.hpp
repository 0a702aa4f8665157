// `modelc build --scene FILE`: builds the image of every model the scene names, and
// `modelc accuracy --model FILE`: the modal model's error and cost against DNIOS.
#pragma once

#include <CLI/CLI.hpp>

namespace trainer::tools::modelc {

void add_build_command(CLI::App& app, int& exit_code);
void add_accuracy_command(CLI::App& app, int& exit_code);

}  // namespace trainer::tools::modelc
