// Cotin's tensor model's trade study: probe presses, the direct reference with every covered
// node imposed, per-cap force errors and the solve's cycle cost (tensor_tradeoff.hpp).
#include "trainer/model_offline/tensor_tradeoff.hpp"

#include "elapsed.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numeric>
#include <utility>

#include "cycle_cost_summary.hpp"
#include "trainer/model/tensor_image.hpp"
#include "trainer/model_offline/image_writer.hpp"
#include "trainer/model_offline/tensor_build.hpp"
#include "trainer/model_offline/tet_mesh_generators.hpp"

namespace trainer::model::offline {

namespace {

using Clock = cycle_cost::Clock;
using RowMatrixX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

// Copies of the cost loop's contacts with depths scaled by ±10 %, cycled through so consecutive
// solves differ without any work in the timed region.
constexpr int kCostVariants = 16;

std::string tradeoff_number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", value);
  return text;
}

std::vector<int> sorted_unique(std::vector<int> nodes) {
  std::sort(nodes.begin(), nodes.end());
  nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
  return nodes;
}

using detail::seconds_since;

// The runtime's quasi-non-linear force rule (TensorModel::solve): the total force's part along
// the push `direction` (unit, or zero: no map) goes through force_colinear and the rest
// through force_orthogonal; each contact keeps its linear share of both, i.e. its parts along
// and across are scaled by the totals' ratios, which this applies to every row of `forces_n`.
void map_contact_forces(const QuasiNonLinearMaps& maps, const Eigen::Vector3d& direction,
                        RowMatrixX3& forces_n) {
  if (direction.squaredNorm() == 0.0) return;
  const Eigen::Vector3d total = forces_n.colwise().sum().transpose();
  const double along = total.dot(direction);
  const double across = (total - along * direction).norm();
  const double along_scale =
      along != 0.0 ? std::copysign(static_cast<double>(maps.force_colinear.evaluate(
                                       static_cast<float>(std::fabs(along)))),
                                   along) / along
                   : 1.0;
  const double across_scale =
      across > 0.0 ? static_cast<double>(maps.force_orthogonal.evaluate(static_cast<float>(across))) /
                         across
                   : 1.0;
  for (Eigen::Index i = 0; i < forces_n.rows(); ++i) {
    const Eigen::Vector3d force = forces_n.row(i).transpose();
    const Eigen::Vector3d part_along = force.dot(direction) * direction;
    forces_n.row(i) = (along_scale * part_along + across_scale * (force - part_along)).transpose();
  }
}

core::Expected<void> check_scenario(const TensorProbeScenario& scenario) {
  const auto refuse = [&](const std::string& what) {
    return core::make_error("tensor trade study: scenario '" + scenario.name + "': " + what);
  };
  if (!scenario.surface_point_m.allFinite()) return refuse("surface point is not finite");
  if (!scenario.inward.allFinite() || std::abs(scenario.inward.norm() - 1.0) > 1e-6) {
    return refuse("inward direction of norm " + tradeoff_number(scenario.inward.norm()) +
                  ", expected a unit vector");
  }
  if (!(scenario.radius_m > 0.0) || !std::isfinite(scenario.radius_m)) {
    return refuse("radius " + tradeoff_number(scenario.radius_m) + " m, expected finite and > 0");
  }
  if (scenario.depths_m.empty()) return refuse("no depths");
  for (const double depth : scenario.depths_m) {
    if (!(depth > 0.0 && depth < scenario.radius_m)) {
      return refuse("depth " + tradeoff_number(depth) + " m, expected in (0, radius = " +
                    tradeoff_number(scenario.radius_m) + " m)");
    }
  }
  return {};
}

// The contact nodes covered by the probe at `centre`, deepest first, and their projections.
TensorTradeStudy::Press covered_press(const TetMesh& mesh, std::span<const int> contact_nodes,
                                      const Eigen::Vector3d& centre, double radius_m,
                                      double depth_m) {
  struct Covered {
    std::uint32_t node;
    double distance_m;
  };
  std::vector<Covered> covered;
  for (const int node : contact_nodes) {
    const double distance = (mesh.nodes.row(node).transpose() - centre).norm();
    if (distance < radius_m && distance > 0.0) {
      covered.push_back({static_cast<std::uint32_t>(node), distance});
    }
  }
  std::sort(covered.begin(), covered.end(), [](const Covered& a, const Covered& b) {
    return a.distance_m != b.distance_m ? a.distance_m < b.distance_m : a.node < b.node;
  });
  TensorTradeStudy::Press press;
  press.depth_m = depth_m;
  press.centre_m = centre;
  for (const Covered& c : covered) {
    const Eigen::Vector3d x = mesh.nodes.row(c.node).transpose();
    press.nodes.push_back(c.node);
    press.displacements_m.push_back(centre + radius_m * (x - centre) / c.distance_m - x);
  }
  return press;
}


// The force on the tissue at covered node `index` pulls when it points towards the probe's
// centre: the radial direction (x − c)/|x − c| is the sphere's outward normal there.
bool pulls(const TetMesh& mesh, const TensorTradeStudy::Press& press, std::size_t index,
           const Eigen::Vector3d& force_n) {
  const Eigen::Vector3d outward = mesh.nodes.row(press.nodes[index]).transpose() - press.centre_m;
  return force_n.dot(outward) < 0.0;
}

// The runtime's answer for the covered nodes `set` (indices into press.nodes): solves, then
// releases every pulling node and solves again until none pulls (or none is left). `set` keeps
// the nodes that pushed; returns the total force on the tissue (zero if every node let go).
core::Expected<Eigen::Vector3d> solve_runtime(TensorModel& model, const TetMesh& mesh,
                                              const TensorTradeStudy::Press& press,
                                              bool release_pulling, std::vector<std::size_t>& set,
                                              std::vector<TensorContact>& contacts) {
  while (true) {
    contacts.clear();
    for (const std::size_t index : set) {
      contacts.push_back({press.nodes[index], press.displacements_m[index].cast<float>()});
    }
    if (const core::Status solved = model.solve(contacts); !solved.is_ok()) {
      return core::make_error(std::string("the runtime refused the solve: ") + solved.detail());
    }
    if (!release_pulling) break;
    std::vector<std::size_t> pushing;
    for (std::size_t i = 0; i < set.size(); ++i) {
      if (!pulls(mesh, press, set[i], model.contact_force(i).cast<double>())) {
        pushing.push_back(set[i]);
      }
    }
    if (pushing.size() == set.size()) break;
    set = std::move(pushing);
  }
  return Eigen::Vector3d(model.total_force().cast<double>());
}

}  // namespace

std::string TensorTradeConfig::label() const {
  char text[16];
  std::snprintf(text, sizeof text, "m%u", max_contacts);
  return text;
}

core::Expected<std::vector<TensorProbeScenario>> default_tensor_scenarios(
    const TetMesh& mesh, std::span<const int> contact_nodes) {
  if (mesh.nodes.rows() == 0) return core::make_error("tensor probe scenarios: empty mesh");
  const double top_z = mesh.nodes.col(2).maxCoeff();
  const double extent = (mesh.nodes.colwise().maxCoeff() - mesh.nodes.colwise().minCoeff()).norm();
  std::vector<int> top;
  for (const int node : contact_nodes) {
    if (mesh.nodes(node, 2) >= top_z - 1e-9 * extent) top.push_back(node);
  }
  if (top.size() < 2) {
    return core::make_error("tensor probe scenarios: " + std::to_string(top.size()) +
                            " contact node(s) on the top face z = " + tradeoff_number(top_z) +
                            " m, expected at least 2 (the probes press the top face along -z)");
  }
  std::vector<double> spacing;
  for (const int a : top) {
    double nearest = std::numeric_limits<double>::infinity();
    for (const int b : top) {
      if (a != b) nearest = std::min(nearest, (mesh.nodes.row(a) - mesh.nodes.row(b)).norm());
    }
    spacing.push_back(nearest);
  }
  std::nth_element(spacing.begin(), spacing.begin() + static_cast<std::ptrdiff_t>(spacing.size() / 2),
                   spacing.end());
  const double h = spacing[spacing.size() / 2];
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d high = -low;
  for (const int node : top) {
    low = low.cwiseMin(mesh.nodes.row(node).transpose());
    high = high.cwiseMax(mesh.nodes.row(node).transpose());
  }
  const Eigen::Vector3d centre = 0.5 * (low + high);
  const int central_node = *std::min_element(top.begin(), top.end(), [&](int a, int b) {
    return (mesh.nodes.row(a).transpose() - centre).squaredNorm() <
           (mesh.nodes.row(b).transpose() - centre).squaredNorm();
  });
  const auto probe = [](std::string name, std::string description, bool tuning,
                        const Eigen::Vector3d& point, double radius_m,
                        std::vector<double> depth_fractions) {
    TensorProbeScenario s;
    s.name = std::move(name);
    s.description = std::move(description);
    s.tuning = tuning;
    s.surface_point_m = point;
    s.inward = -Eigen::Vector3d::UnitZ();
    s.radius_m = radius_m;
    for (const double fraction : depth_fractions) s.depths_m.push_back(fraction * radius_m);
    return s;
  };
  const double small = 0.55 * h;
  const double large = 1.6 * h;
  const double wide = 2.7 * h;
  std::vector<TensorProbeScenario> scenarios;
  scenarios.push_back(probe("small-probe-on-node",
                            "R = 0.55 h over the top node nearest the centre, 0.3 and 0.6 R deep",
                            true, mesh.nodes.row(central_node).transpose(), small, {0.3, 0.6}));
  scenarios.push_back(probe("probe-centre", "R = 1.6 h at the top face's centre, 0.2-0.5 R deep",
                            true, centre, large, {0.2, 0.35, 0.5}));
  scenarios.push_back(probe("probe-off-node",
                            "R = 1.6 h, centre shifted (0.37 h, 0.23 h), 0.25 and 0.45 R deep",
                            false, centre + Eigen::Vector3d(0.37 * h, 0.23 * h, 0.0), large,
                            {0.25, 0.45}));
  scenarios.push_back(probe("wide-probe", "R = 2.7 h at the centre, 0.2 and 0.4 R deep", false,
                            centre, wide, {0.2, 0.4}));
  scenarios.push_back(probe("probe-near-edge",
                            "R = 1.6 h, 0.3 h inside the +x edge (overlaps the side face), "
                            "0.25 and 0.45 R deep",
                            false, Eigen::Vector3d(high.x() - 0.3 * h, centre.y(), top_z), large,
                            {0.25, 0.45}));
  return scenarios;
}

std::size_t TensorTradeStudy::largest_contact_set() const {
  std::size_t largest = 0;
  for (const auto& presses : presses_) {
    for (const Press& press : presses) largest = std::max(largest, press.contact_set.size());
  }
  return largest;
}

core::Expected<std::unique_ptr<TensorTradeStudy>> TensorTradeStudy::create(
    TensorStudySpec spec, std::vector<TensorProbeScenario> scenarios) {
  if (scenarios.empty()) return core::make_error("tensor trade study: no scenarios");
  for (const TensorProbeScenario& scenario : scenarios) {
    auto checked = check_scenario(scenario);
    if (!checked) return std::move(checked).error();
  }
  std::unique_ptr<TensorTradeStudy> study(new TensorTradeStudy());
  study->spec_ = std::move(spec);
  study->scenarios_ = std::move(scenarios);
  const TetMesh& mesh = study->spec_.mesh;

  // The image, as `modelc build` makes it (tools/modelc build_tensor_model).
  const auto start = Clock::now();
  auto assembled = assemble_tet(mesh, study->spec_.material, study->spec_.fixes);
  if (!assembled) return std::move(assembled).error();
  auto solver = TetStaticSolver::create(*assembled);
  if (!solver) return std::move(solver).error();
  const std::vector<int> fixed_nodes = partly_fixed_nodes(assembled->dofs);
  const auto contact_set = mesh.node_sets.find(study->spec_.contact_set);
  if (contact_set == mesh.node_sets.end()) {
    return core::make_error("tensor trade study: contact set '" + study->spec_.contact_set +
                            "' is not a node set of the mesh");
  }
  TensorPrecomputeOptions options;
  const std::vector<int> candidates = sorted_unique(contact_set->second);
  std::set_difference(candidates.begin(), candidates.end(), fixed_nodes.begin(), fixed_nodes.end(),
                      std::back_inserter(options.contact_nodes));
  if (options.contact_nodes.empty()) {
    return core::make_error("tensor trade study: contact set '" + study->spec_.contact_set +
                            "' has no node free on all three axes");
  }
  std::vector<int> stored = options.contact_nodes;
  if (const auto surface = mesh.node_sets.find("surface"); surface != mesh.node_sets.end()) {
    stored.insert(stored.end(), surface->second.begin(), surface->second.end());
  }
  options.response_nodes = sorted_unique(std::move(stored));
  options.contacts_per_block = study->spec_.contacts_per_block;
  auto tensors = precompute_tensors(*assembled, *solver, options);
  if (!tensors) return std::move(tensors).error();
  TensorImageInputs inputs;
  inputs.mesh = &mesh;
  inputs.boundary_triangles = boundary_triangles(mesh);
  inputs.material = study->spec_.material;
  inputs.fixed_nodes = fixed_nodes;
  inputs.time_step_s = 1e-3;
  auto bytes = serialize_tensor_image(inputs, *tensors);
  if (!bytes) return std::move(bytes).error();
  auto arena = core::Arena::create(bytes->size() + core::Arena::kAlignment);
  if (!arena) return std::move(arena).error();
  study->image_arena_ = std::make_unique<core::Arena>(std::move(*arena));
  auto block = study->image_arena_->allocate_array<std::byte>(bytes->size(), "tensor image");
  if (!block) return std::move(block).error();
  std::memcpy(block->data(), bytes->data(), bytes->size());
  auto image = parse_model_image(*block, "trade study image", ModelKind::tet_tensor,
                                 ImageWriter::permissive_limits());
  if (!image) return std::move(image).error();
  study->image_ = std::move(*image);
  study->image_bytes_ = bytes->size();
  study->contact_nodes_ = options.contact_nodes;
  study->stored_node_count_ = options.response_nodes.size();
  study->precompute_s_ = seconds_since(start);

  // Every press: the covered nodes, the contact set (the runtime proposes which nodes pull; the
  // direct solve confirms it, releasing more if it disagrees) and the direct reference.
  const auto reference_start = Clock::now();
  const auto guess_capacity = static_cast<std::uint32_t>(
      std::min<std::size_t>(TensorModel::kMaxContactsLimit, study->contact_nodes_.size()));
  auto guess_arena = core::Arena::create(9 * std::size_t{guess_capacity} * guess_capacity *
                                             sizeof(double) +
                                         3 * study->stored_node_count_ * sizeof(float) +
                                         sizeof(std::int32_t) * study->contact_nodes_.size() +
                                         (std::size_t{1} << 16));
  if (!guess_arena) return std::move(guess_arena).error();
  TensorSettings guess_settings;
  guess_settings.max_contacts = guess_capacity;
  guess_settings.nonlinear = study->spec_.nonlinear;
  auto guess = TensorModel::create(tensor_model_data(study->image_), guess_settings, *guess_arena);
  if (!guess) return std::move(guess).error();
  std::vector<TensorContact> contacts;
  for (const TensorProbeScenario& scenario : study->scenarios_) {
    std::vector<Press> presses;
    for (const double depth_m : scenario.depths_m) {
      const Eigen::Vector3d centre =
          scenario.surface_point_m + (depth_m - scenario.radius_m) * scenario.inward;
      Press press = covered_press(mesh, study->contact_nodes_, centre, scenario.radius_m, depth_m);
      const auto where = [&] {
        return "tensor trade study: scenario '" + scenario.name + "' at depth " + tradeoff_number(depth_m) +
               " m";
      };
      if (press.nodes.empty()) {
        return core::make_error(where() + " covers no contact node (probe radius " +
                                tradeoff_number(scenario.radius_m) +
                                " m): move it onto a node, press deeper or use a larger probe");
      }
      press.contact_set.resize(press.nodes.size());
      std::iota(press.contact_set.begin(), press.contact_set.end(), std::size_t{0});
      if (study->spec_.release_pulling_nodes && press.nodes.size() <= guess_capacity) {
        auto proposed = solve_runtime(*guess, mesh, press, true, press.contact_set, contacts);
        if (!proposed) return core::make_error(where() + ": " + proposed.error().message);
      }
      while (true) {
        if (press.contact_set.empty()) {
          return core::make_error(where() + ": every covered node pulls, none pushes");
        }
        std::vector<int> nodes;
        RowMatrixX3 imposed(static_cast<Eigen::Index>(press.contact_set.size()), 3);
        Eigen::Vector3d push = Eigen::Vector3d::Zero();
        for (std::size_t i = 0; i < press.contact_set.size(); ++i) {
          const std::size_t index = press.contact_set[i];
          nodes.push_back(static_cast<int>(press.nodes[index]));
          imposed.row(static_cast<Eigen::Index>(i)) = press.displacements_m[index].transpose();
          push += press.displacements_m[index];
        }
        auto direct = solve_imposed_displacements(*assembled, nodes, imposed);
        ++press.reference_solves;
        if (!direct) return core::make_error(where() + " reference: " + direct.error().message);
        RowMatrixX3 forces = direct->contact_forces;
        const Eigen::Vector3d direction =
            push.norm() > 0.0 ? Eigen::Vector3d(push.normalized()) : Eigen::Vector3d::Zero();
        map_contact_forces(study->spec_.nonlinear, direction, forces);
        std::vector<std::size_t> pushing;
        for (std::size_t i = 0; i < press.contact_set.size(); ++i) {
          const Eigen::Vector3d force = forces.row(static_cast<Eigen::Index>(i)).transpose();
          if (!study->spec_.release_pulling_nodes ||
              !pulls(mesh, press, press.contact_set[i], force)) {
            pushing.push_back(press.contact_set[i]);
          }
        }
        if (pushing.size() < press.contact_set.size()) {
          press.contact_set = std::move(pushing);
          continue;
        }
        press.reference_force_n = forces.colwise().sum().transpose();
        break;
      }
      presses.push_back(std::move(press));
    }
    study->presses_.push_back(std::move(presses));
  }
  study->reference_solve_s_ = seconds_since(reference_start);
  return study;
}

core::Expected<TensorTradePoint> TensorTradeStudy::measure(
    const TensorTradeConfig& config, const CycleCostOptions& cost_options) const {
  auto options_ok = cycle_cost::check_options(cost_options, "tensor trade study");
  if (!options_ok) return std::move(options_ok).error();
  const std::uint32_t cap = config.max_contacts;
  if (cap > contact_nodes_.size()) {
    return core::make_error("tensor trade study: " + config.label() + ": the model has only " +
                            std::to_string(contact_nodes_.size()) + " contact nodes");
  }
  TensorSettings settings;
  settings.max_contacts = cap;
  settings.nonlinear = spec_.nonlinear;
  // The solver state is (3m)² + 3m doubles and a few arrays of m, the field 3 floats per stored
  // node, the contact map one int per contact node; 64 KiB more covers the alignment.
  const std::size_t state_estimate = 9 * std::size_t{cap} * cap * sizeof(double) +
                                     16 * std::size_t{cap} * sizeof(double) +
                                     3 * stored_node_count_ * sizeof(float) +
                                     sizeof(std::int32_t) * contact_nodes_.size() +
                                     (std::size_t{1} << 16);
  auto arena = core::Arena::create(state_estimate);
  if (!arena) return std::move(arena).error();
  auto model = TensorModel::create(tensor_model_data(image_), settings, *arena);
  if (!model) {
    return core::make_error("tensor trade study: " + config.label() + ": " +
                            model.error().message);
  }
  TensorTradePoint point;
  point.config = config;
  point.state_bytes = arena->used_bytes();

  std::vector<TensorContact> contacts;
  contacts.reserve(cap);
  for (std::size_t index = 0; index < scenarios_.size(); ++index) {
    const TensorProbeScenario& scenario = scenarios_[index];
    TensorScenarioError error;
    error.scenario = scenario.name;
    error.tuning = scenario.tuning;
    error.radius_m = scenario.radius_m;
    for (const Press& press : presses_[index]) {
      std::vector<std::size_t> set(
          press.contact_set.begin(),
          press.contact_set.begin() +
              static_cast<std::ptrdiff_t>(std::min<std::size_t>(cap, press.contact_set.size())));
      auto solved = solve_runtime(*model, spec_.mesh, press, spec_.release_pulling_nodes, set,
                                  contacts);
      if (!solved) {
        return core::make_error("tensor trade study: scenario '" + scenario.name + "' at depth " +
                                tradeoff_number(press.depth_m) + " m, " + config.label() + ": " +
                                solved.error().message);
      }
      const Eigen::Vector3d& force = *solved;
      const double reference = press.reference_force_n.norm();
      error.force_error =
          std::max(error.force_error, (force - press.reference_force_n).norm() / reference);
      const double cosine = force.norm() > 0.0
                                ? std::clamp(force.dot(press.reference_force_n) /
                                                 (force.norm() * reference), -1.0, 1.0)
                                : -1.0;
      error.direction_error_rad = std::max(error.direction_error_rad, std::acos(cosine));
      // The deepest press is the last: its counts describe the scenario.
      error.covered_nodes = static_cast<int>(press.nodes.size());
      error.contact_nodes = static_cast<int>(press.contact_set.size());
      error.imposed_nodes = static_cast<int>(set.size());
      error.reference_force_n = reference;
    }
    double& bucket = scenario.tuning ? point.tuning_error : point.validation_error;
    bucket = std::max(bucket, error.force_error);
    point.worst_error = std::max(point.worst_error, error.force_error);
    point.errors.push_back(std::move(error));
  }

  // Cost: the largest contact set, deepest first, completed by the nearest other contact nodes
  // held in place.
  const Press* busiest = &presses_.front().front();
  for (const auto& presses : presses_) {
    for (const Press& press : presses) {
      if (press.contact_set.size() > busiest->contact_set.size()) busiest = &press;
    }
  }
  std::vector<TensorContact> base;
  for (std::size_t i = 0; i < std::min<std::size_t>(cap, busiest->contact_set.size()); ++i) {
    const std::size_t index = busiest->contact_set[i];
    base.push_back({busiest->nodes[index], busiest->displacements_m[index].cast<float>()});
  }
  if (base.size() < cap) {
    std::vector<int> others;
    for (const int node : contact_nodes_) {
      const bool taken = std::any_of(base.begin(), base.end(), [&](const TensorContact& c) {
        return c.node == static_cast<std::uint32_t>(node);
      });
      if (!taken) others.push_back(node);
    }
    const auto distance = [&](int node) {
      return (spec_.mesh.nodes.row(node).transpose() - busiest->centre_m).squaredNorm();
    };
    std::partial_sort(others.begin(),
                      others.begin() + static_cast<std::ptrdiff_t>(cap - base.size()),
                      others.end(), [&](int a, int b) { return distance(a) < distance(b); });
    for (std::size_t i = 0; base.size() < cap; ++i) {
      base.push_back({static_cast<std::uint32_t>(others[i]), Vec3::Zero()});
    }
  }
  std::vector<std::vector<TensorContact>> variants(kCostVariants, base);
  for (int v = 0; v < kCostVariants; ++v) {
    const float scale = 1.0F + 0.1F * static_cast<float>(std::sin(0.7 * v));
    for (TensorContact& contact : variants[static_cast<std::size_t>(v)]) {
      contact.displacement_m *= scale;
    }
  }
  const int timed = cost_options.repetitions * cost_options.cycles_per_repetition;
  std::vector<double> total_ns;
  std::vector<double> haptic_ns;
  total_ns.reserve(static_cast<std::size_t>(timed));
  haptic_ns.reserve(static_cast<std::size_t>(timed));
  for (int c = 0; c < cost_options.warmup_cycles + timed; ++c) {
    const std::vector<TensorContact>& imposed =
        variants[static_cast<std::size_t>(c % kCostVariants)];
    const auto cycle_start = Clock::now();
    const core::Status solved = model->solve(imposed);
    const auto solved_at = Clock::now();
    model->update_field();
    const auto end = Clock::now();
    if (!solved.is_ok()) {
      return core::make_error("tensor trade study: " + config.label() +
                              ": cost loop: the runtime refused the solve: " + solved.detail());
    }
    if (c < cost_options.warmup_cycles) continue;
    total_ns.push_back(cycle_cost::nanoseconds(end - cycle_start));
    haptic_ns.push_back(cycle_cost::nanoseconds(solved_at - cycle_start));
  }
  point.cost = cycle_cost::summarize(cost_options, total_ns, haptic_ns);
  return point;
}

}  // namespace trainer::model::offline
