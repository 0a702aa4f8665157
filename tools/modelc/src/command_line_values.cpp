// Parsing of modelc's compound option values (see command_line_values.hpp).
#include "command_line_values.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string_view>

namespace trainer::tools::modelc {
namespace {

using model::offline::BendingElement;

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t end = text.find(separator, start);
    parts.push_back(text.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return parts;
}

std::string trim(const std::string& text) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return {};
  const auto last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

double parse_real(const std::string& text, const std::string& context) {
  const std::string value = trim(text);
  double result = 0.0;
  const char* first = value.data();
  const char* last = first + value.size();
  if (first != last && *first == '+') ++first;
  const auto [end, error] = std::from_chars(first, last, result);
  if (value.empty() || error != std::errc() || end != last || !std::isfinite(result)) {
    throw std::invalid_argument(context + ": '" + text + "' is not a finite number");
  }
  return result;
}

int parse_int(const std::string& text, const std::string& context) {
  const std::string value = trim(text);
  int result = 0;
  const auto [end, error] = std::from_chars(value.data(), value.data() + value.size(), result);
  if (value.empty() || error != std::errc() || end != value.data() + value.size()) {
    throw std::invalid_argument(context + ": '" + text + "' is not an integer");
  }
  return result;
}

// Splits "GROUP=REST" at the first '='.
std::pair<std::string, std::string> split_group(const std::string& text, const std::string& option,
                                                const std::string& expected) {
  const std::size_t equals = text.find('=');
  if (equals == std::string::npos || trim(text.substr(0, equals)).empty()) {
    throw std::invalid_argument(option + " '" + text + "': expected " + expected);
  }
  return {trim(text.substr(0, equals)), text.substr(equals + 1)};
}

}  // namespace

model::offline::DofFix parse_fix(const std::string& text) {
  const std::string expected = "GROUP=DOFS with DOFS a comma list of x,y,z,rx,ry,rz or 'all'";
  auto [group, list] = split_group(text, "--fix", expected);
  model::offline::DofFix fix;
  fix.node_set = group;
  for (const std::string& raw : split(list, ',')) {
    const std::string name = trim(raw);
    if (name == "all") {
      for (int dof = 0; dof < model::offline::kShellDofsPerNode; ++dof) fix.dofs.push_back(dof);
    } else if (name == "x" || name == "ux") {
      fix.dofs.push_back(model::offline::kUx);
    } else if (name == "y" || name == "uy") {
      fix.dofs.push_back(model::offline::kUy);
    } else if (name == "z" || name == "uz") {
      fix.dofs.push_back(model::offline::kUz);
    } else if (name == "rx") {
      fix.dofs.push_back(model::offline::kRx);
    } else if (name == "ry") {
      fix.dofs.push_back(model::offline::kRy);
    } else if (name == "rz") {
      fix.dofs.push_back(model::offline::kRz);
    } else {
      throw std::invalid_argument("--fix '" + text + "': unknown dof '" + name + "'; expected " +
                                  expected);
    }
  }
  std::sort(fix.dofs.begin(), fix.dofs.end());
  fix.dofs.erase(std::unique(fix.dofs.begin(), fix.dofs.end()), fix.dofs.end());
  return fix;
}

GroupVector parse_group_vector(const std::string& text, const std::string& option) {
  const std::string expected = "GROUP=X,Y,Z (three numbers, SI units, global frame)";
  auto [group, list] = split_group(text, option, expected);
  const std::vector<std::string> parts = split(list, ',');
  if (parts.size() != 3) {
    throw std::invalid_argument(option + " '" + text + "': expected " + expected);
  }
  GroupVector result;
  result.group = group;
  for (int i = 0; i < 3; ++i) {
    result.value(i) = parse_real(parts[static_cast<std::size_t>(i)], option + " '" + text + "'");
  }
  return result;
}

TubeSpec parse_tube(const std::string& text) {
  const std::vector<std::string> parts = split(text, ',');
  const std::string context = "--tube '" + text + "'";
  if (parts.size() != 4) {
    throw std::invalid_argument(context +
                                ": expected R,L,RINGS,SEGMENTS (radius m, length m, "
                                "node rings >= 2, nodes per ring >= 3)");
  }
  TubeSpec tube;
  tube.radius_m = parse_real(parts[0], context + " radius");
  tube.length_m = parse_real(parts[1], context + " length");
  tube.rings = parse_int(parts[2], context + " rings");
  tube.segments = parse_int(parts[3], context + " segments");
  return tube;
}

BendingElement parse_element(const std::string& text) {
  if (text == "shell-rao") return BendingElement::rao;
  if (text == "shell-dkt") return BendingElement::dkt;
  throw std::invalid_argument("--element '" + text + "': expected shell-rao or shell-dkt");
}

const char* element_name(BendingElement element) {
  return element == BendingElement::rao ? "shell-rao" : "shell-dkt";
}

}  // namespace trainer::tools::modelc
