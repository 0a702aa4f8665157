// Shell mesh checks before assembly (see mesh_validation.hpp for the list).
#include "trainer/model_offline/mesh_validation.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <numeric>
#include <sstream>
#include <string>
#include <tuple>
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

// Interior angle (degrees) of triangle t at its corner `corner`.
double corner_angle_deg(const ShellMesh& mesh, Eigen::Index t, int corner) {
  const Eigen::RowVector3d at = mesh.nodes.row(mesh.triangles(t, corner));
  const Eigen::RowVector3d to_next = mesh.nodes.row(mesh.triangles(t, (corner + 1) % 3)) - at;
  const Eigen::RowVector3d to_previous = mesh.nodes.row(mesh.triangles(t, (corner + 2) % 3)) - at;
  return std::atan2(to_next.cross(to_previous).norm(), to_next.dot(to_previous)) * 180.0 /
         std::numbers::pi;
}

std::array<int, 3> sorted_nodes(const ShellMesh& mesh, Eigen::Index t) {
  std::array<int, 3> nodes{mesh.triangles(t, 0), mesh.triangles(t, 1), mesh.triangles(t, 2)};
  std::sort(nodes.begin(), nodes.end());
  return nodes;
}

}  // namespace

CoincidentNodes find_coincident_nodes(
    const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>& nodes, double ratio,
    std::size_t max_pairs) {
  CoincidentNodes result;
  if (nodes.rows() == 0) return result;
  const Eigen::RowVector3d lower = nodes.colwise().minCoeff();
  const Eigen::RowVector3d upper = nodes.colwise().maxCoeff();
  result.tolerance_m = ratio * (upper - lower).norm();
  std::vector<int> order(static_cast<std::size_t>(nodes.rows()));
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int l, int r) { return nodes(l, 0) < nodes(r, 0); });
  for (std::size_t i = 0; i < order.size() && result.pairs.size() < max_pairs; ++i) {
    for (std::size_t j = i + 1; j < order.size() && result.pairs.size() < max_pairs; ++j) {
      const int a = order[i];
      const int b = order[j];
      if (nodes(b, 0) - nodes(a, 0) > result.tolerance_m) break;
      if ((nodes.row(a) - nodes.row(b)).norm() <= result.tolerance_m) {
        result.pairs.emplace_back(std::min(a, b), std::max(a, b));
      }
    }
  }
  return result;
}

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

  // Slivers: the smallest interior angle of every non-degenerate triangle.
  for (Eigen::Index t = 0; t < triangle_count && !problems.full(); ++t) {
    if (!(areas[static_cast<std::size_t>(t)] > kDegenerateAreaRatio * mean_area)) continue;
    double smallest_deg = 180.0;
    int smallest_corner = 0;
    for (int corner = 0; corner < 3; ++corner) {
      const double angle = corner_angle_deg(mesh, t, corner);
      if (angle < smallest_deg) {
        smallest_deg = angle;
        smallest_corner = corner;
      }
    }
    if (smallest_deg < kMinTriangleAngleDeg) {
      std::ostringstream out;
      out << "triangle " << t << " (nodes " << mesh.triangles(t, 0) << ", " << mesh.triangles(t, 1)
          << ", " << mesh.triangles(t, 2) << "): sliver, smallest angle " << smallest_deg
          << " deg at node " << mesh.triangles(t, smallest_corner) << "; expected >= "
          << kMinTriangleAngleDeg << " deg (remesh)";
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

  // Orientation: an edge shared by exactly two triangles must be run in opposite directions.
  // Edges of duplicate triangles (reported above) and of non-manifold edges are not judged.
  struct EdgeUse {
    int low, high;
    bool forward;  // the triangle runs low → high
    Eigen::Index triangle;
    bool operator<(const EdgeUse& other) const {
      return std::tie(low, high, triangle) < std::tie(other.low, other.high, other.triangle);
    }
  };
  std::vector<EdgeUse> edges;
  edges.reserve(static_cast<std::size_t>(3 * triangle_count));
  for (Eigen::Index t = 0; t < triangle_count; ++t) {
    for (int corner = 0; corner < 3; ++corner) {
      const int from = mesh.triangles(t, corner);
      const int to = mesh.triangles(t, (corner + 1) % 3);
      edges.push_back({std::min(from, to), std::max(from, to), from < to, t});
    }
  }
  std::sort(edges.begin(), edges.end());
  for (std::size_t i = 0; i < edges.size() && !problems.full();) {
    std::size_t end = i + 1;
    while (end < edges.size() && edges[end].low == edges[i].low &&
           edges[end].high == edges[i].high) {
      ++end;
    }
    const EdgeUse& first = edges[i];
    const EdgeUse& second = edges[end - 1];
    if (end - i == 2 && first.forward == second.forward &&
        sorted_nodes(mesh, first.triangle) != sorted_nodes(mesh, second.triangle)) {
      const int from = first.forward ? first.low : first.high;
      const int to = first.forward ? first.high : first.low;
      problems.add("triangles " + std::to_string(first.triangle) + " and " +
                   std::to_string(second.triangle) + ": inconsistent orientation, both run along "
                   "their shared edge " + std::to_string(from) + "->" + std::to_string(to) +
                   " (neighbours must run along it in opposite directions so that their "
                   "normals point to the same side); reverse the node order of the inverted one");
    }
    i = end;
  }

  // Duplicate nodes.
  const CoincidentNodes coincident = find_coincident_nodes(mesh.nodes, kCoincidentNodeRatio, 8);
  for (const auto& [first, second] : coincident.pairs) {
    if (problems.full()) break;
    std::ostringstream out;
    out << "node " << second << ": duplicate of node " << first << " at "
        << point_text(mesh.nodes.row(first)) << " (coincident within " << coincident.tolerance_m
        << " m)";
    problems.add(out.str());
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
