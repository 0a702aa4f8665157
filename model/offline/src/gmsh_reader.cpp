// Gmsh MSH 4.1 ASCII reader (see gmsh_reader.hpp for what is read and how groups map).
// Parsing throws a private ParseError carrying the line; the public functions catch it and
// return core::Error("file:line: message").
#include "trainer/model_offline/gmsh_reader.hpp"

#include <xxhash.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <fstream>
#include <set>
#include <sstream>
#include <system_error>
#include <unordered_map>
#include <utility>

namespace trainer::model::offline {
namespace {

struct ParseError {
  int line = 0;
  std::string message;
};

struct Token {
  std::string_view text;
  int line = 0;
};

class Lexer {
 public:
  explicit Lexer(std::string_view text) : text_(text) {}

  // Line of the last token read (or of the current position before any).
  int line() const { return last_line_; }
  int current_line() const { return line_; }

  bool at_end() {
    skip_whitespace(true);
    return position_ >= text_.size();
  }

  Token next(const std::string& what) {
    skip_whitespace(true);
    if (position_ >= text_.size()) {
      throw ParseError{line_, "expected " + what + ", found the end of the file"};
    }
    return take_token();
  }

  std::int64_t integer(const std::string& what) {
    const Token token = next(what);
    std::int64_t value = 0;
    const char* first = token.text.data();
    const char* last = first + token.text.size();
    const auto [end, error] = std::from_chars(first, last, value);
    if (error != std::errc() || end != last) {
      throw ParseError{token.line, "expected " + what + " (an integer), found '" +
                                       std::string(token.text) + "'"};
    }
    return value;
  }

  int small_integer(const std::string& what, std::int64_t minimum, std::int64_t maximum) {
    const std::int64_t value = integer(what);
    if (value < minimum || value > maximum) {
      throw ParseError{last_line_, what + " = " + std::to_string(value) + ": expected " +
                                       std::to_string(minimum) + ".." + std::to_string(maximum)};
    }
    return static_cast<int>(value);
  }

  double real(const std::string& what) {
    const Token token = next(what);
    double value = 0.0;
    const char* first = token.text.data();
    const char* last = first + token.text.size();
    if (first != last && *first == '+') ++first;
    const auto [end, error] = std::from_chars(first, last, value);
    if (error != std::errc() || end != last) {
      throw ParseError{token.line,
                       "expected " + what + " (a number), found '" + std::string(token.text) + "'"};
    }
    return value;
  }

  void expect(std::string_view keyword) {
    const Token token = next(std::string(keyword));
    if (token.text != keyword) {
      throw ParseError{token.line, "expected " + std::string(keyword) + ", found '" +
                                       std::string(token.text) +
                                       "' (a count in the section "
                                       "header does not match its contents?)"};
    }
  }

  // Tokens of the next non-empty line.
  std::vector<Token> line_tokens() {
    skip_whitespace(true);
    std::vector<Token> tokens;
    while (true) {
      skip_whitespace(false);
      if (position_ >= text_.size() || text_[position_] == '\n') break;
      tokens.push_back(take_token());
    }
    return tokens;
  }

  // The rest of the current line (without the newline), consumed.
  std::string_view rest_of_line() {
    const std::size_t start = position_;
    while (position_ < text_.size() && text_[position_] != '\n') ++position_;
    return text_.substr(start, position_ - start);
  }

 private:
  void skip_whitespace(bool newlines) {
    while (position_ < text_.size()) {
      const char c = text_[position_];
      if (c == '\n') {
        if (!newlines) return;
        ++line_;
      } else if (c != ' ' && c != '\t' && c != '\r') {
        return;
      }
      ++position_;
    }
  }

  Token take_token() {
    const std::size_t start = position_;
    while (position_ < text_.size()) {
      const char c = text_[position_];
      if (c == ' ' || c == '\t' || c == '\r' || c == '\n') break;
      ++position_;
    }
    last_line_ = line_;
    return Token{text_.substr(start, position_ - start), line_};
  }

  std::string_view text_;
  std::size_t position_ = 0;
  int line_ = 1;
  int last_line_ = 1;
};

constexpr int kTypePoint = 15;
constexpr int kTypeLine = 1;
constexpr int kTypeTriangle = 2;
constexpr int kTypeTetrahedron = 4;

int known_node_count(int type) {
  switch (type) {
    case kTypePoint: return 1;
    case kTypeLine: return 2;
    case kTypeTriangle: return 3;
    case kTypeTetrahedron: return 4;
    default: return -1;
  }
}

std::string type_name(int type) {
  switch (type) {
    case 3: return "4-node quadrangle";
    case 5: return "8-node hexahedron";
    case 6: return "6-node prism";
    case 7: return "5-node pyramid";
    case 8: return "3-node line";
    case 9: return "6-node triangle";
    case 10: return "9-node quadrangle";
    case 11: return "10-node tetrahedron";
    case 16: return "8-node quadrangle";
    default: return "type " + std::to_string(type);
  }
}

using EntityKey = std::pair<int, int>;  // (dimension, tag)

struct ElementBlock {
  int dimension = 0;
  int entity_tag = 0;
  int type = 0;
  int header_line = 0;
  int nodes_per_element = 0;
  std::vector<std::size_t> node_indices;  // raw node indices, nodes_per_element per element
  std::vector<int> lines;                 // file line of each element
};

struct RawMesh {
  std::vector<Eigen::Vector3d> positions;
  std::vector<std::int64_t> node_tags;
  std::map<EntityKey, std::string> physical_names;
  std::map<EntityKey, std::vector<int>> entity_groups;  // entity → physical group tags
  bool has_entities = false;
  int physical_names_line = 0;
  std::vector<ElementBlock> blocks;
};

void skip_section(Lexer& lexer, std::string_view name, int start_line) {
  const std::string end = "$End" + std::string(name);
  while (true) {
    if (lexer.at_end()) {
      throw ParseError{start_line, "section $" + std::string(name) + " has no " + end};
    }
    if (lexer.next(end).text == end) return;
  }
}

void parse_mesh_format(Lexer& lexer) {
  const Token version = lexer.next("the MSH version");
  if (version.text != "4.1") {
    throw ParseError{version.line, "unsupported MSH version " + std::string(version.text) +
                                       "; expected 4.1 (gmsh -format msh41, ASCII)"};
  }
  const std::int64_t file_type = lexer.integer("the MSH file-type (0 = ASCII)");
  if (file_type != 0) {
    throw ParseError{lexer.line(),
                     "binary MSH files are not supported; expected ASCII (file-type "
                     "0), found file-type " +
                         std::to_string(file_type)};
  }
  lexer.integer("the MSH data-size");
  lexer.expect("$EndMeshFormat");
}

void parse_physical_names(Lexer& lexer, RawMesh& raw) {
  const int count = lexer.small_integer("the number of physical names", 0, 1 << 24);
  for (int i = 0; i < count; ++i) {
    const int dimension = lexer.small_integer("a physical group dimension", 0, 3);
    const int tag = lexer.small_integer("a physical group tag", 1, 1 << 30);
    const int line = lexer.line();
    std::string_view name = lexer.rest_of_line();
    while (!name.empty() && (name.front() == ' ' || name.front() == '\t')) name.remove_prefix(1);
    while (!name.empty() && (name.back() == ' ' || name.back() == '\t' || name.back() == '\r')) {
      name.remove_suffix(1);
    }
    if (name.size() < 2 || name.front() != '"' || name.back() != '"') {
      throw ParseError{line,
                       "expected a quoted physical group name, found '" + std::string(name) + "'"};
    }
    raw.physical_names[{dimension, tag}] = std::string(name.substr(1, name.size() - 2));
  }
  lexer.expect("$EndPhysicalNames");
}

void parse_entities(Lexer& lexer, RawMesh& raw) {
  raw.has_entities = true;
  std::array<int, 4> counts{};
  const std::array<const char*, 4> names{"points", "curves", "surfaces", "volumes"};
  for (std::size_t d = 0; d < 4; ++d) {
    counts[d] = lexer.small_integer(std::string("the number of ") + names[d], 0, 1 << 30);
  }
  for (int dimension = 0; dimension < 4; ++dimension) {
    for (int e = 0; e < counts[static_cast<std::size_t>(dimension)]; ++e) {
      const int tag = lexer.small_integer("an entity tag", -(1 << 30), 1 << 30);
      const int coordinates = dimension == 0 ? 3 : 6;
      for (int c = 0; c < coordinates; ++c) lexer.real("an entity coordinate");
      const int physical_count = lexer.small_integer("the number of physical tags", 0, 1 << 20);
      std::vector<int> groups;
      for (int p = 0; p < physical_count; ++p) {
        // Gmsh writes a negative tag for a group whose orientation is reversed.
        const int group = lexer.small_integer("a physical tag", -(1 << 30), 1 << 30);
        groups.push_back(group < 0 ? -group : group);
      }
      raw.entity_groups[{dimension, tag}] = std::move(groups);
      if (dimension > 0) {
        const int bounding = lexer.small_integer("the number of bounding entities", 0, 1 << 24);
        for (int b = 0; b < bounding; ++b) lexer.integer("a bounding entity tag");
      }
    }
  }
  lexer.expect("$EndEntities");
}

void parse_nodes(Lexer& lexer, RawMesh& raw,
                 std::unordered_map<std::int64_t, std::size_t>& index_of_tag) {
  const int blocks = lexer.small_integer("the number of node blocks", 0, 1 << 30);
  const std::int64_t total = lexer.integer("the number of nodes");
  const int header_line = lexer.line();
  lexer.integer("the minimum node tag");
  lexer.integer("the maximum node tag");
  if (total < 0 || total > (std::int64_t{1} << 31)) {
    throw ParseError{header_line, "bad node count " + std::to_string(total)};
  }
  raw.positions.reserve(static_cast<std::size_t>(total));
  std::int64_t read = 0;
  for (int b = 0; b < blocks; ++b) {
    const int dimension = lexer.small_integer("a node block's entity dimension", 0, 3);
    lexer.integer("a node block's entity tag");
    const int parametric = lexer.small_integer("a node block's parametric flag", 0, 1);
    const std::int64_t count = lexer.integer("a node block's node count");
    const int block_line = lexer.line();
    if (count < 0 || read + count > total) {
      throw ParseError{block_line, "node block " + std::to_string(b + 1) + " has " +
                                       std::to_string(count) + " nodes, more than the " +
                                       std::to_string(total) +
                                       " the $Nodes header announces in all"};
    }
    for (std::int64_t n = 0; n < count; ++n) {
      const std::int64_t tag = lexer.integer("a node tag");
      if (!index_of_tag.emplace(tag, raw.node_tags.size()).second) {
        throw ParseError{lexer.line(), "node tag " + std::to_string(tag) + " appears twice"};
      }
      raw.node_tags.push_back(tag);
    }
    for (std::int64_t n = 0; n < count; ++n) {
      Eigen::Vector3d p;
      for (int c = 0; c < 3; ++c) p(c) = lexer.real("a node coordinate");
      if (parametric) {
        for (int c = 0; c < dimension; ++c) lexer.real("a parametric coordinate");
      }
      raw.positions.push_back(p);
    }
    read += count;
  }
  if (read != total) {
    throw ParseError{header_line, "the $Nodes header announces " + std::to_string(total) +
                                      " nodes but its " + std::to_string(blocks) + " blocks hold " +
                                      std::to_string(read)};
  }
  lexer.expect("$EndNodes");
}

void parse_elements(Lexer& lexer, RawMesh& raw,
                    const std::unordered_map<std::int64_t, std::size_t>& index_of_tag) {
  const int blocks = lexer.small_integer("the number of element blocks", 0, 1 << 30);
  const std::int64_t total = lexer.integer("the number of elements");
  const int header_line = lexer.line();
  lexer.integer("the minimum element tag");
  lexer.integer("the maximum element tag");
  std::int64_t read = 0;
  for (int b = 0; b < blocks; ++b) {
    ElementBlock block;
    block.dimension = lexer.small_integer("an element block's entity dimension", 0, 3);
    block.entity_tag = lexer.small_integer("an element block's entity tag", -(1 << 30), 1 << 30);
    block.type = lexer.small_integer("an element type", 1, 1 << 16);
    const std::int64_t count = lexer.integer("an element block's element count");
    block.header_line = lexer.line();
    if (count < 0 || read + count > total) {
      throw ParseError{block.header_line, "element block " + std::to_string(b + 1) + " has " +
                                              std::to_string(count) + " elements, more than the " +
                                              std::to_string(total) +
                                              " the $Elements header announces in all"};
    }
    block.nodes_per_element = known_node_count(block.type);
    for (std::int64_t e = 0; e < count; ++e) {
      const std::vector<Token> tokens = lexer.line_tokens();
      const int line = tokens.empty() ? lexer.current_line() : tokens.front().line;
      if (tokens.empty() || tokens.front().text.front() == '$') {
        throw ParseError{line, "element block " + std::to_string(b + 1) + " announces " +
                                   std::to_string(count) + " elements but has only " +
                                   std::to_string(e)};
      }
      const int nodes = static_cast<int>(tokens.size()) - 1;
      if (block.nodes_per_element < 0) block.nodes_per_element = nodes;
      if (nodes != block.nodes_per_element) {
        throw ParseError{line, "element of " + type_name(block.type) + " (type " +
                                   std::to_string(block.type) + ") has " + std::to_string(nodes) +
                                   " node tags; expected " +
                                   std::to_string(block.nodes_per_element)};
      }
      for (std::size_t t = 1; t < tokens.size(); ++t) {
        std::int64_t tag = 0;
        const char* first = tokens[t].text.data();
        const char* last = first + tokens[t].text.size();
        const auto [end, error] = std::from_chars(first, last, tag);
        if (error != std::errc() || end != last) {
          throw ParseError{line, "expected a node tag (an integer), found '" +
                                     std::string(tokens[t].text) + "'"};
        }
        const auto found = index_of_tag.find(tag);
        if (found == index_of_tag.end()) {
          throw ParseError{line, "element " + std::string(tokens[0].text) + " uses node tag " +
                                     std::to_string(tag) + ", which $Nodes does not define"};
        }
        block.node_indices.push_back(found->second);
      }
      block.lines.push_back(line);
    }
    read += count;
    raw.blocks.push_back(std::move(block));
  }
  if (read != total) {
    throw ParseError{header_line, "the $Elements header announces " + std::to_string(total) +
                                      " elements but its " + std::to_string(blocks) +
                                      " blocks hold " + std::to_string(read)};
  }
  lexer.expect("$EndElements");
}

RawMesh parse_raw(std::string_view text) {
  Lexer lexer(text);
  RawMesh raw;
  std::unordered_map<std::int64_t, std::size_t> index_of_tag;
  bool has_format = false, has_nodes = false, has_elements = false;
  std::set<std::string> seen;
  while (!lexer.at_end()) {
    const Token header = lexer.next("a section header");
    if (header.text.size() < 2 || header.text.front() != '$') {
      throw ParseError{header.line, "expected a section header ($Name), found '" +
                                        std::string(header.text) + "'"};
    }
    const std::string name(header.text.substr(1));
    if (!has_format && name != "MeshFormat") {
      throw ParseError{header.line, "expected $MeshFormat as the first section, found $" + name};
    }
    if (!seen.insert(name).second &&
        (name == "MeshFormat" || name == "Nodes" || name == "Elements" || name == "Entities" ||
         name == "PhysicalNames")) {
      throw ParseError{header.line, "section $" + name + " appears twice"};
    }
    if (name == "MeshFormat") {
      parse_mesh_format(lexer);
      has_format = true;
    } else if (name == "PhysicalNames") {
      raw.physical_names_line = header.line;
      parse_physical_names(lexer, raw);
    } else if (name == "Entities") {
      parse_entities(lexer, raw);
    } else if (name == "Nodes") {
      parse_nodes(lexer, raw, index_of_tag);
      has_nodes = true;
    } else if (name == "Elements") {
      if (!has_nodes) throw ParseError{header.line, "$Elements comes before $Nodes"};
      parse_elements(lexer, raw, index_of_tag);
      has_elements = true;
    } else {
      skip_section(lexer, name, header.line);
    }
  }
  const int last_line = lexer.current_line();
  if (!has_format) throw ParseError{last_line, "missing $MeshFormat section (not an MSH file?)"};
  if (!has_nodes) throw ParseError{last_line, "missing $Nodes section"};
  if (!has_elements) throw ParseError{last_line, "missing $Elements section"};
  if (!raw.physical_names.empty() && !raw.has_entities) {
    throw ParseError{raw.physical_names_line,
                     "$PhysicalNames present but the $Entities section that assigns entities to "
                     "physical groups is missing"};
  }
  return raw;
}

// Physical group names of an element block (empty when the entity has none).
std::vector<std::string> block_groups(const RawMesh& raw, const ElementBlock& block) {
  std::vector<std::string> names;
  if (!raw.has_entities) return names;
  const auto found = raw.entity_groups.find({block.dimension, block.entity_tag});
  if (found == raw.entity_groups.end()) {
    throw ParseError{block.header_line, "element block refers to entity (dimension " +
                                            std::to_string(block.dimension) + ", tag " +
                                            std::to_string(block.entity_tag) +
                                            ") that $Entities does not define"};
  }
  for (const int group : found->second) {
    const auto name = raw.physical_names.find({block.dimension, group});
    names.push_back(name != raw.physical_names.end() ? name->second : std::to_string(group));
  }
  return names;
}

// Elements of types the models cannot represent are refused where they matter.
void check_block_type(const ElementBlock& block, const std::vector<std::string>& groups) {
  if (known_node_count(block.type) > 0) return;
  if (!groups.empty()) {
    throw ParseError{block.header_line, "unsupported element type " + std::to_string(block.type) +
                                            " (" + type_name(block.type) +
                                            ") used by physical group '" + groups.front() +
                                            "'; expected points (15), 2-node lines (1), "
                                            "3-node triangles (2) or 4-node tetrahedra (4)"};
  }
  if (block.dimension >= 2) {
    throw ParseError{block.header_line,
                     "unsupported " + std::to_string(block.dimension) + "-D element type " +
                         std::to_string(block.type) + " (" + type_name(block.type) +
                         "): the models use only 3-node triangles and 4-node tetrahedra"};
  }
}

// Renumbering of the nodes used by elements of `kept_type`, in file order.
struct Renumbering {
  std::vector<int> new_index;  // raw index → new index or −1
  int count = 0;
};

Renumbering renumber_nodes(const RawMesh& raw, int kept_type) {
  Renumbering result;
  std::vector<char> used(raw.positions.size(), 0);
  for (const ElementBlock& block : raw.blocks) {
    if (block.type != kept_type) continue;
    for (const std::size_t index : block.node_indices) used[index] = 1;
  }
  result.new_index.assign(raw.positions.size(), -1);
  for (std::size_t i = 0; i < used.size(); ++i) {
    if (used[i]) result.new_index[i] = result.count++;
  }
  return result;
}

template <class Matrix>
void fill_nodes(const RawMesh& raw, const Renumbering& numbering, Matrix& nodes) {
  nodes.resize(numbering.count, 3);
  for (std::size_t i = 0; i < raw.positions.size(); ++i) {
    const int index = numbering.new_index[i];
    if (index >= 0) nodes.row(index) = raw.positions[i].transpose();
  }
}

void sort_unique(std::map<std::string, std::vector<int>>& sets) {
  for (auto& [name, members] : sets) {
    std::sort(members.begin(), members.end());
    members.erase(std::unique(members.begin(), members.end()), members.end());
  }
}

// Adds an element's nodes to its groups' node sets; every node must survive the renumbering.
void add_group_nodes(const RawMesh& raw, const Renumbering& numbering, const ElementBlock& block,
                     std::size_t element, const std::vector<std::string>& groups,
                     const char* kept_kind, std::map<std::string, std::vector<int>>& node_sets) {
  const auto nodes = static_cast<std::size_t>(block.nodes_per_element);
  for (std::size_t k = 0; k < nodes; ++k) {
    const std::size_t raw_index = block.node_indices[element * nodes + k];
    const int index = numbering.new_index[raw_index];
    if (index < 0) {
      throw ParseError{block.lines[element], "physical group '" + groups.front() + "' (dimension " +
                                                 std::to_string(block.dimension) +
                                                 ") uses node tag " +
                                                 std::to_string(raw.node_tags[raw_index]) +
                                                 ", which no " + kept_kind + " uses"};
    }
    for (const std::string& group : groups) node_sets[group].push_back(index);
  }
}

ShellMesh build_shell(const RawMesh& raw) {
  const Renumbering numbering = renumber_nodes(raw, kTypeTriangle);
  if (numbering.count == 0) {
    throw ParseError{1,
                     "no 3-node triangles (element type 2) in the file; the shell model "
                     "needs a triangulated surface"};
  }
  ShellMesh mesh;
  fill_nodes(raw, numbering, mesh.nodes);
  std::vector<std::array<int, 3>> triangles;
  for (const ElementBlock& block : raw.blocks) {
    const std::vector<std::string> groups = block_groups(raw, block);
    check_block_type(block, groups);
    if (block.dimension == 3) continue;
    for (std::size_t e = 0; e < block.lines.size(); ++e) {
      if (block.type == kTypeTriangle) {
        std::array<int, 3> triangle{};
        for (std::size_t k = 0; k < 3; ++k) {
          triangle[k] = numbering.new_index[block.node_indices[3 * e + k]];
        }
        for (const std::string& group : groups) {
          mesh.triangle_sets[group].push_back(static_cast<int>(triangles.size()));
        }
        triangles.push_back(triangle);
      }
      if (!groups.empty()) {
        add_group_nodes(raw, numbering, block, e, groups, "triangle", mesh.node_sets);
      }
    }
  }
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    mesh.triangles.row(static_cast<Eigen::Index>(t)) << triangles[t][0], triangles[t][1],
        triangles[t][2];
  }
  sort_unique(mesh.node_sets);
  return mesh;
}

TetMesh build_tet(const RawMesh& raw) {
  const Renumbering numbering = renumber_nodes(raw, kTypeTetrahedron);
  if (numbering.count == 0) {
    throw ParseError{1,
                     "no 4-node tetrahedra (element type 4) in the file; the tetrahedral "
                     "model needs a volume mesh"};
  }
  TetMesh mesh;
  fill_nodes(raw, numbering, mesh.nodes);
  std::vector<std::array<int, 4>> tetrahedra;
  std::vector<std::array<int, 3>> triangles;
  for (const ElementBlock& block : raw.blocks) {
    const std::vector<std::string> groups = block_groups(raw, block);
    check_block_type(block, groups);
    for (std::size_t e = 0; e < block.lines.size(); ++e) {
      if (!groups.empty()) {
        add_group_nodes(raw, numbering, block, e, groups, "tetrahedron", mesh.node_sets);
      }
      if (block.type == kTypeTetrahedron) {
        std::array<int, 4> tetrahedron{};
        for (std::size_t k = 0; k < 4; ++k) {
          tetrahedron[k] = numbering.new_index[block.node_indices[4 * e + k]];
        }
        for (const std::string& group : groups) {
          mesh.tetrahedron_sets[group].push_back(static_cast<int>(tetrahedra.size()));
        }
        tetrahedra.push_back(tetrahedron);
      } else if (block.type == kTypeTriangle) {
        std::array<int, 3> triangle{};
        bool on_tetrahedra = true;
        for (std::size_t k = 0; k < 3; ++k) {
          triangle[k] = numbering.new_index[block.node_indices[3 * e + k]];
          on_tetrahedra = on_tetrahedra && triangle[k] >= 0;
        }
        if (!on_tetrahedra) continue;  // only possible outside groups (checked above)
        for (const std::string& group : groups) {
          mesh.triangle_sets[group].push_back(static_cast<int>(triangles.size()));
        }
        triangles.push_back(triangle);
      }
    }
  }
  mesh.tetrahedra.resize(static_cast<Eigen::Index>(tetrahedra.size()), 4);
  for (std::size_t t = 0; t < tetrahedra.size(); ++t) {
    for (std::size_t k = 0; k < 4; ++k) {
      mesh.tetrahedra(static_cast<Eigen::Index>(t), static_cast<Eigen::Index>(k)) =
          tetrahedra[t][k];
    }
  }
  mesh.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    mesh.triangles.row(static_cast<Eigen::Index>(t)) << triangles[t][0], triangles[t][1],
        triangles[t][2];
  }
  sort_unique(mesh.node_sets);
  return mesh;
}

std::uint64_t hash_bytes(std::string_view text) {
  return XXH64(text.data(), text.size(), 0);
}

template <class Mesh, class Build>
core::Expected<Mesh> parse_with(std::string_view text, const std::string& source_name,
                                Build&& build) {
  try {
    Mesh mesh = build(parse_raw(text));
    mesh.source_hash = hash_bytes(text);
    return mesh;
  } catch (const ParseError& error) {
    return core::make_error(source_name + ":" + std::to_string(error.line) + ": " + error.message);
  }
}

core::Expected<std::string> read_file(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    return core::make_error(path + ": cannot open the mesh file (" +
                            std::generic_category().message(errno) + ")");
  }
  std::ostringstream contents;
  contents << file.rdbuf();
  if (file.bad()) return core::make_error(path + ": read error");
  return contents.str();
}

}  // namespace

core::Expected<ShellMesh> parse_gmsh_shell(std::string_view text, const std::string& source_name) {
  return parse_with<ShellMesh>(text, source_name, build_shell);
}

core::Expected<TetMesh> parse_gmsh_tet(std::string_view text, const std::string& source_name) {
  return parse_with<TetMesh>(text, source_name, build_tet);
}

core::Expected<ShellMesh> read_gmsh_shell(const std::string& path) {
  auto text = read_file(path);
  if (!text) return text.error();
  return parse_gmsh_shell(*text, path);
}

core::Expected<TetMesh> read_gmsh_tet(const std::string& path) {
  auto text = read_file(path);
  if (!text) return text.error();
  return parse_gmsh_tet(*text, path);
}

}  // namespace trainer::model::offline
