// Shell mesh checks before assembly (see mesh_validation.hpp for the list).
#include "trainer/model_offline/mesh_validation.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numeric>
#include <sstream>
#include <string>
#include <vector>

namespace trainer::model::offline {
namespace {

constexpr int kMaxReportedProblems = 8;

class ProblemList {
 public:
  // Returns false once enough problems are collected, so callers can stop scanning.
  bool add(const std::string& problem) {
    ++count_;
    if (count_ <= kMaxReportedProblems) problems_.push_back(problem);
    return count_ < kMaxReportedProblems;
  }
  bool full() const { return count_ >= kMaxReportedProblems; }
  bool empty() const { return count_ == 0; }
  std::string message() const {
    std::ostringstream out;
    out << "invalid shell mesh: ";
    for (std::size_t i = 0; i < problems_.size(); ++i) {
      if (i > 0) out << "\n  ";
      out << problems_[i];
    }
    if (count_ > kMaxReportedProblems) out << "\n  (further problems not listed)";
    return out.str();
  }

 private:
  std::vector<std::string> problems_;
  int count_ = 0;
};

std::string point_text(const Eigen::RowVector3d& p) {
  std::ostringstream out;
  out.precision(9);
  out << "(" << p(0) << ", " << p(1) << ", " << p(2) << ")";
  return out.str();
}

void check_sets(const std::map<std::string, std::vector<int>>& sets, const char* kind,
                const char* member, Eigen::Index limit, ProblemList& problems) {
  for (const auto& [name, members] : sets) {
    if (members.empty()) {
      problems.add(std::string(kind) + " '" + name + "' is empty");
      continue;
    }
    for (const int index : members) {
      if (index < 0 || index >= limit) {
        problems.add(std::string(kind) + " '" + name + "' lists " + member + " " +
                     std::to_string(index) + ", outside 0.." + std::to_string(limit - 1));
        break;
      }
    }
  }
}

}  // namespace

core::Expected<void> validate_shell_mesh(const ShellMesh& mesh) {
  const Eigen::Index node_count = mesh.nodes.rows();
  const Eigen::Index triangle_count = mesh.triangles.rows();
  if (node_count == 0 || triangle_count == 0) {
    return core::make_error("invalid shell mesh: it has " + std::to_string(node_count) +
                            " nodes and " + std::to_string(triangle_count) +
                            " triangles; expected at least 3 nodes and 1 triangle");
  }
  ProblemList problems;

  for (Eigen::Index n = 0; n < node_count && !problems.full(); ++n) {
    if (!mesh.nodes.row(n).allFinite()) {
      problems.add("node " + std::to_string(n) + ": non-finite coordinates");
    }
  }
  if (!problems.empty()) return core::make_error(problems.message());

  // Index checks first: the geometric checks below need valid indices.
  std::vector<char> used(static_cast<std::size_t>(node_count), 0);
  for (Eigen::Index t = 0; t < triangle_count; ++t) {
    bool valid = true;
    for (int corner = 0; corner < 3; ++corner) {
      const int node = mesh.triangles(t, corner);
      if (node < 0 || node >= node_count) {
        problems.add("triangle " + std::to_string(t) + ": node index " + std::to_string(node) +
                     " out of range 0.." + std::to_string(node_count - 1));
        valid = false;
        break;
      }
    }
    if (!valid) continue;
    const int a = mesh.triangles(t, 0), b = mesh.triangles(t, 1), c = mesh.triangles(t, 2);
    if (a == b || b == c || a == c) {
      problems.add("triangle " + std::to_string(t) + ": repeats a node (" + std::to_string(a) +
                   ", " + std::to_string(b) + ", " + std::to_string(c) + ")");
      continue;
    }
    for (int corner = 0; corner < 3; ++corner) {
      used[static_cast<std::size_t>(mesh.triangles(t, corner))] = 1;
    }
  }
  check_sets(mesh.node_sets, "node set", "node", node_count, problems);
  check_sets(mesh.triangle_sets, "triangle set", "triangle", triangle_count, problems);
  if (!problems.empty()) return core::make_error(problems.message());

  // Degenerate triangles, relative to the mesh's mean area.
  std::vector<double> areas(static_cast<std::size_t>(triangle_count));
  for (Eigen::Index t = 0; t < triangle_count; ++t) {
    const Eigen::RowVector3d p0 = mesh.nodes.row(mesh.triangles(t, 0));
    const Eigen::RowVector3d p1 = mesh.nodes.row(mesh.triangles(t, 1));
    const Eigen::RowVector3d p2 = mesh.nodes.row(mesh.triangles(t, 2));
    areas[static_cast<std::size_t>(t)] = 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  const double mean_area =
      std::accumulate(areas.begin(), areas.end(), 0.0) / static_cast<double>(triangle_count);
  for (Eigen::Index t = 0; t < triangle_count && !problems.full(); ++t) {
    const double area = areas[static_cast<std::size_t>(t)];
    if (!(area > kDegenerateAreaRatio * mean_area)) {
      std::ostringstream out;
      out << "triangle " << t << " (nodes " << mesh.triangles(t, 0) << ", " << mesh.triangles(t, 1)
          << ", " << mesh.triangles(t, 2) << "): degenerate, area " << area << " m^2 vs mean "
          << mean_area << " m^2";
      problems.add(out.str());
    }
  }

  // Duplicate triangles: same node set in any order.
  std::vector<std::pair<std::array<int, 3>, Eigen::Index>> sorted_triangles;
  sorted_triangles.reserve(static_cast<std::size_t>(triangle_count));
  for (Eigen::Index t = 0; t < triangle_count; ++t) {
    std::array<int, 3> key{mesh.triangles(t, 0), mesh.triangles(t, 1), mesh.triangles(t, 2)};
    std::sort(key.begin(), key.end());
    sorted_triangles.emplace_back(key, t);
  }
  std::sort(sorted_triangles.begin(), sorted_triangles.end());
  for (std::size_t i = 1; i < sorted_triangles.size() && !problems.full(); ++i) {
    if (sorted_triangles[i].first == sorted_triangles[i - 1].first) {
      problems.add("triangle " + std::to_string(sorted_triangles[i].second) +
                   ": duplicate of triangle " + std::to_string(sorted_triangles[i - 1].second) +
                   " (same nodes)");
    }
  }

  // Duplicate nodes: sweep along x, comparing only nodes within the tolerance in x.
  const Eigen::RowVector3d lower = mesh.nodes.colwise().minCoeff();
  const Eigen::RowVector3d upper = mesh.nodes.colwise().maxCoeff();
  const double tolerance = kCoincidentNodeRatio * (upper - lower).norm();
  std::vector<int> order(static_cast<std::size_t>(node_count));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int l, int r) { return mesh.nodes(l, 0) < mesh.nodes(r, 0); });
  for (std::size_t i = 0; i < order.size() && !problems.full(); ++i) {
    for (std::size_t j = i + 1; j < order.size(); ++j) {
      const int a = order[i];
      const int b = order[j];
      if (mesh.nodes(b, 0) - mesh.nodes(a, 0) > tolerance) break;
      if ((mesh.nodes.row(a) - mesh.nodes.row(b)).norm() <= tolerance) {
        std::ostringstream out;
        out << "node " << std::max(a, b) << ": duplicate of node " << std::min(a, b) << " at "
            << point_text(mesh.nodes.row(a)) << " (coincident within " << tolerance << " m)";
        problems.add(out.str());
      }
    }
  }

  for (Eigen::Index n = 0; n < node_count && !problems.full(); ++n) {
    if (!used[static_cast<std::size_t>(n)]) {
      problems.add("node " + std::to_string(n) +
                   ": used by no triangle (it would have no stiffness)");
    }
  }

  if (!problems.empty()) return core::make_error(problems.message());
  return {};
}

}  // namespace trainer::model::offline
