// modelc: the offline model compiler's command line. Each job is a subcommand registered by
// its own file (static_command.cpp today; `build --scene FILE` joins the same way).
#include <exception>
#include <iostream>

#include <CLI/CLI.hpp>

#include "build_command.hpp"
#include "catheter_command.hpp"
#include "static_command.hpp"

int main(int argc, char** argv) {
  CLI::App app{"modelc: offline model compiler for the haptic trainer (SI units throughout)"};
  app.require_subcommand(1);
  int exit_code = 0;
  trainer::tools::modelc::add_static_command(app, exit_code);
  trainer::tools::modelc::add_build_command(app, exit_code);
  trainer::tools::modelc::add_accuracy_command(app, exit_code);
  trainer::tools::modelc::add_catheter_static_command(app, exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    return app.exit(error);
  } catch (const std::exception& error) {
    std::cerr << "modelc: " << error.what() << "\n";
    return 1;
  }
  return exit_code;
}
