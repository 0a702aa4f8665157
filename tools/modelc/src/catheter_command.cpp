#include "catheter_command.hpp"

#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "trainer/model_offline/catheter_static.hpp"

namespace trainer::tools::modelc {

namespace {

struct CatheterStaticOptions {
  double length_m = 0.0;
  double ei = 0.0;
  double ea = 0.0;
  std::uint32_t particles = 0;
  std::string tip_force;
  std::string report_path;
};

Eigen::Vector3d parse_vector(const std::string& text, const std::string& option) {
  Eigen::Vector3d value = Eigen::Vector3d::Zero();
  std::size_t start = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const std::size_t comma = text.find(',', start);
    const std::string field = text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (field.empty() || (axis < 2 && comma == std::string::npos) || (axis == 2 && comma != std::string::npos)) {
      throw std::runtime_error(option + " " + text + ": expected three comma-separated numbers FX,FY,FZ (N)");
    }
    std::size_t used = 0;
    try {
      value[axis] = std::stod(field, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used != field.size() || !std::isfinite(value[axis])) {
      throw std::runtime_error(option + " " + text + ": '" + field + "' is not a finite number");
    }
    start = comma + 1;
  }
  return value;
}

void run_catheter_static(const CatheterStaticOptions& options) {
  model::offline::CatheterStaticInput input;
  input.length_m = options.length_m;
  input.bending_stiffness_n_m2 = options.ei;
  input.axial_stiffness_n = options.ea;
  input.particle_count = options.particles;
  input.tip_force_n = parse_vector(options.tip_force, "--tip-force");
  auto result = model::offline::solve_catheter_static(input);
  if (!result) throw std::runtime_error(result.error().message);
  const Eigen::Vector3d& tip = result->tip_position_m;
  const Eigen::Vector3d& displacement = result->tip_displacement_m;
  std::cout << "catheter L " << options.length_m << " m, EI " << options.ei << " N m^2, EA "
            << options.ea << " N, " << options.particles << " particles, tip force ["
            << input.tip_force_n.transpose() << "] N\n"
            << "  tip position [" << tip.transpose() << "] m, displacement ["
            << displacement.transpose() << "] m (|d| = " << displacement.norm() << " m)\n"
            << "  tip rotation " << result->tip_rotation_rad << " rad, " << result->iterations
            << " Newton iterations, residual " << result->residual_n << " N\n";
  nlohmann::json report = {
      {"length_m", options.length_m},
      {"bending_stiffness_n_m2", options.ei},
      {"axial_stiffness_n", options.ea},
      {"particle_count", options.particles},
      {"tip_force_n", {input.tip_force_n.x(), input.tip_force_n.y(), input.tip_force_n.z()}},
      {"tip_position_m", {tip.x(), tip.y(), tip.z()}},
      {"tip_displacement_m", {displacement.x(), displacement.y(), displacement.z()}},
      {"tip_rotation_rad", result->tip_rotation_rad},
      {"newton_iterations", result->iterations},
      {"residual_n", result->residual_n},
  };
  std::ofstream out(options.report_path);
  out << report.dump(2) << "\n";
  if (!out) throw std::runtime_error("cannot write report '" + options.report_path + "'");
  std::cout << "report: " << options.report_path << "\n";
}

}  // namespace

void add_catheter_static_command(CLI::App& app, int& exit_code) {
  auto options = std::make_shared<CatheterStaticOptions>();
  CLI::App* command = app.add_subcommand(
      "catheter-static",
      "Particle catheter (Basdogan eq. 27) along +x from the origin, clamped there (position and "
      "tangent), settled to static equilibrium under a tip force of fixed direction; large "
      "deflections included. SI units: m, N, N m^2.");
  command->add_option("--length", options->length_m, "catheter length L (m), > 0")->required();
  command->add_option("--ei", options->ei, "bending stiffness EI (N m^2), > 0")->required();
  command->add_option("--ea", options->ea, "axial stiffness EA (N), > 0")->required();
  command->add_option("--particles", options->particles, "particle count N (3..256)")->required();
  command->add_option("--tip-force", options->tip_force, "FX,FY,FZ: tip force (N), fixed direction")
      ->required();
  command->add_option("--report", options->report_path, "JSON report to write")->required();
  command->callback([options, &exit_code] {
    run_catheter_static(*options);
    exit_code = 0;
  });
}

}  // namespace trainer::tools::modelc
