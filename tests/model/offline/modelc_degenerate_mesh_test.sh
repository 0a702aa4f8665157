#!/usr/bin/env bash
# The real `modelc` binary refuses every kind of degenerate Gmsh mesh with a clear message:
# exit status 1 and an error naming the element or node and the problem. Small MSH 4.1 files
# are written into a temporary directory; each defect is one change to an otherwise valid mesh,
# and the valid mesh itself must be accepted (so a refusal is the defect's, not the file's).
#   shell (modelc static --element shell-dkt): zero-area triangle, sliver (smallest angle
#     below 1 deg), duplicate node, duplicate triangle, inconsistently oriented triangle;
#   tet4 (modelc static --element tet4): flat (zero-volume) tetrahedron, inverted
#     tetrahedron, sliver (dihedral angle below 1 deg), needle (face angle below 1 deg),
#     duplicate node (a crack);
#   and the scene build path (modelc build --scene) for a shell and a tet sliver.
# usage: modelc_degenerate_mesh_test.sh MODELC REPO_ROOT
set -euo pipefail
modelc=$1
repo=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Writes MSH 4.1 files: nodes (tags 1..n in order, so node index = tag − 1), triangles and
# tetrahedra (element index = position in its list), physical groups "fixed" (point elements on
# the listed nodes), "surface" (every triangle), "solid" (every tetrahedron).
cat >"$work/msh.py" <<'PY'
import sys

def write(path, nodes, triangles=(), tets=(), fixed=()):
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", "$PhysicalNames"]
    names = [(0, 1, "fixed")]
    if triangles: names.append((2, 2, "surface"))
    if tets: names.append((3, 3, "solid"))
    out.append(str(len(names)))
    out += [f'{d} {t} "{n}"' for d, t, n in names]
    out += ["$EndPhysicalNames", "$Entities",
            f"1 0 {1 if triangles else 0} {1 if tets else 0}", "1 0 0 0 1 1"]
    if triangles: out.append("1 0 0 0 1 1 1 1 2 0")
    if tets: out.append("1 0 0 0 1 1 1 1 3 0")
    out.append("$EndEntities")
    dim = 3 if tets else 2
    out += ["$Nodes", f"1 {len(nodes)} 1 {len(nodes)}", f"{dim} 1 0 {len(nodes)}"]
    out += [str(i + 1) for i in range(len(nodes))]
    out += [" ".join(repr(float(c)) for c in p) for p in nodes]
    out.append("$EndNodes")
    blocks = [(0, 15, [[n] for n in fixed])]
    if triangles: blocks.append((2, 2, triangles))
    if tets: blocks.append((3, 4, tets))
    count = sum(len(b[2]) for b in blocks)
    out += ["$Elements", f"{len(blocks)} {count} 1 {count}"]
    tag = 1
    for d, kind, elements in blocks:
        out.append(f"{d} 1 {kind} {len(elements)}")
        for e in elements:
            out.append(" ".join([str(tag)] + [str(n + 1) for n in e]))
            tag += 1
    out.append("$EndElements")
    open(path, "w").write("\n".join(out) + "\n")

# Shell: the unit square, 3 x 3 nodes (index j*3 + i at (i/2, j/2)), quads split along
# (i,j)-(i+1,j+1): triangle 0 = (0, 1, 4), 1 = (0, 4, 3), 2 = (1, 2, 5), ... x = 0 fixed.
def plate():
    nodes = [[i / 2, j / 2, 0.0] for j in range(3) for i in range(3)]
    tris = []
    for j in range(2):
        for i in range(2):
            a, b, c, d = j * 3 + i, j * 3 + i + 1, (j + 1) * 3 + i + 1, (j + 1) * 3 + i
            tris += [[a, b, c], [a, c, d]]
    return nodes, tris

# Tet: unit cubes along x, 8 nodes per cube layer, each cube the 6 Kuhn tetrahedra around its
# (0,0,0)-(1,1,1) diagonal (positive volumes); z = 0 nodes fixed.
def cubes(count, crack=False):
    nodes, tets = [], []
    def node(p):
        nodes.append(p)
        return len(nodes) - 1
    def corner_nodes(x0, shared):
        c = {}
        for k in range(2):
            for j in range(2):
                for i in range(2):
                    key = (i, j, k)
                    if i == 0 and shared is not None:
                        c[key] = shared[(1, j, k)]
                    else:
                        c[key] = node([x0 + i, float(j), float(k)])
        return c
    previous = None
    for cube in range(count):
        shared = previous
        if crack and previous is not None:  # duplicate the shared face's nodes: a crack
            shared = {key: node(nodes[n][:]) for key, n in previous.items() if key[0] == 1}
        c = corner_nodes(float(cube), shared)
        p0, p7 = c[(0, 0, 0)], c[(1, 1, 1)]
        for path in [(1, 0, 0), (0, 1, 0), (0, 0, 1)]:
            for second in [(1, 0, 0), (0, 1, 0), (0, 0, 1)]:
                if second == path: continue
                a = c[path]
                b = c[tuple(path[i] + second[i] for i in range(3))]
                tets.append([p0, a, b, p7])
        previous = c
    # orient every tetrahedron positively
    def volume(t):
        p = [nodes[n] for n in t]
        e = [[p[i][k] - p[0][k] for k in range(3)] for i in (1, 2, 3)]
        return (e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1])
                - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0])
                + e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]))
    tets = [t if volume(t) > 0 else [t[0], t[2], t[1], t[3]] for t in tets]
    fixed = [n for n, p in enumerate(nodes) if p[2] == 0.0]
    return nodes, tets, fixed

def make(case, path):
    if case.startswith("shell"):
        nodes, tris = plate()
        fixed = [0, 3, 6]
        if case == "shell_zero_area":   # node 1 onto the diagonal 0-4: triangle 0 has no area
            nodes[1] = [0.25, 0.25, 0.0]
        elif case == "shell_sliver":    # node 1 almost onto it: a cap with two ~0.1 deg angles
            nodes[1] = [0.2505, 0.2495, 0.0]
        elif case == "shell_duplicate_node":  # node 9 at node 4's place, used by triangle 3
            nodes.append(nodes[4][:])
            tris[3] = [1, 5, 9]
        elif case == "shell_duplicate_triangle":
            tris.append([tris[0][1], tris[0][2], tris[0][0]])
        elif case == "shell_inverted":  # triangle 1 reversed: its normal points to -z
            tris[1] = [tris[1][0], tris[1][2], tris[1][1]]
        elif case != "shell_good":
            raise SystemExit("unknown case " + case)
        write(path, nodes, triangles=tris, fixed=fixed)
    else:
        if case == "tet_duplicate_node":
            nodes, tets, fixed = cubes(2, crack=True)
        elif case == "tet_sliver":      # one tetrahedron: a unit square with a corner lifted 5 mm
            nodes = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.005]]
            tets, fixed = [[0, 1, 2, 3]], [0, 1, 2]
        elif case == "tet_needle":      # a 5 mm right triangle under an apex 1 m above it
            nodes = [[0, 0, 0], [0.005, 0, 0], [0, 0.005, 0], [0, 0, 1.0]]
            tets, fixed = [[0, 1, 2, 3]], [0, 1, 2]
        else:
            nodes, tets, fixed = cubes(2)
            if case == "tet_inverted":
                tets[2] = [tets[2][1], tets[2][0], tets[2][2], tets[2][3]]
            elif case == "tet_flat":    # an extra node in the plane of tetrahedron 0's first face
                a, b, c = (nodes[n] for n in tets[0][:3])
                nodes.append([(a[k] + b[k] + c[k]) / 3 for k in range(3)])
                tets.append([tets[0][0], tets[0][1], tets[0][2], len(nodes) - 1])
            elif case != "tet_good":
                raise SystemExit("unknown case " + case)
        write(path, nodes, tets=tets, fixed=fixed)

for case in sys.argv[2:]:
    make(case, sys.argv[1] + "/" + case + ".msh")
PY

python3 "$work/msh.py" "$work" shell_good shell_zero_area shell_sliver shell_duplicate_node \
  shell_duplicate_triangle shell_inverted tet_good tet_flat tet_inverted tet_sliver tet_needle \
  tet_duplicate_node
failures=0
# run_static CASE EXPECT... : runs modelc static on the case's mesh, checks exit status 1 and
# that every EXPECT string is in the message (EXPECT "accepted" means exit status 0).
run_static() {
  local case=$1
  shift
  local element=(--element shell-dkt --thickness 0.001 --fix fixed=all)
  [[ $case == tet_* ]] && element=(--element tet4 --fix fixed=all)
  local status=0
  "$modelc" static --mesh "$work/$case.msh" "${element[@]}" --young 1e6 --poisson 0.3 \
    --report "$work/$case.json" >"$work/$case.out" 2>&1 || status=$?
  check "$case" "$status" "$work/$case.out" "$@"
}

check() {
  local case=$1 status=$2 output=$3
  shift 3
  if [[ $1 == accepted ]]; then
    if [[ $status -ne 0 ]]; then
      echo "FAIL $case: a valid mesh was refused (status $status):"; cat "$output"
      failures=$((failures + 1))
    else
      echo "ok   $case: accepted"
    fi
    return
  fi
  if [[ $status -ne 1 ]]; then
    echo "FAIL $case: exit status $status, expected 1:"; cat "$output"
    failures=$((failures + 1))
    return
  fi
  for expected in "$@"; do
    if ! grep -qF -- "$expected" "$output"; then
      echo "FAIL $case: the message does not contain '$expected':"; cat "$output"
      failures=$((failures + 1))
      return
    fi
  done
  echo "ok   $case: $(head -n 2 "$output" | tr '\n' ' ')"
}

run_static shell_good accepted
run_static shell_zero_area "invalid shell mesh" "triangle 0 (nodes 0, 1, 4): degenerate, area 0"
run_static shell_sliver "invalid shell mesh" "triangle 0 (nodes 0, 1, 4): sliver, smallest angle" \
  "expected >= 1 deg (remesh)"
run_static shell_duplicate_node "invalid shell mesh" "node 9: duplicate of node 4 at (0.5, 0.5, 0)"
run_static shell_duplicate_triangle "invalid shell mesh" "triangle 8: duplicate of triangle 0 (same nodes)"
run_static shell_inverted "invalid shell mesh" \
  "triangles 0 and 1: inconsistent orientation, both run along their shared edge"
run_static tet_good accepted
run_static tet_flat "tet mesh: tetrahedron 12 (nodes" "is degenerate (volume"
run_static tet_inverted "tet mesh: tetrahedron 2 (nodes" "is inverted (volume"
run_static tet_sliver "tet mesh: tetrahedron 0 (nodes 0, 1, 2, 3) is a sliver (smallest dihedral angle" \
  "expected every dihedral and face angle >= 1 deg: remesh"
run_static tet_needle "tet mesh: tetrahedron 0 (nodes 0, 1, 2, 3) is a needle (smallest face angle" \
  "at node 3 between nodes"
run_static tet_duplicate_node "tet mesh: node 8 is a duplicate of node 1" "the mesh is split there"

# The scene build path: a scene naming a model definition whose mesh is a Gmsh file. The
# scene files are the repository's (their relative paths reach devices/ and trajectories/ through
# links); the model definitions are written here.
mkdir -p "$work/scene/scenes" "$work/scene/models"
ln -s "$repo/config/devices" "$work/scene/devices"
ln -s "$repo/config/trajectories" "$work/scene/trajectories"
cp "$repo/config/scenes/duct.toml" "$repo/config/scenes/liver.toml" "$work/scene/scenes/"
write_duct() {
  cat >"$work/scene/models/duct.toml" <<EOF
[model]
name = "duct"
kind = "modal_shell"
image = "duct.img"
[mesh]
generator = "gmsh"
file = "$work/$1.msh"
[material]
young_modulus_pa = 3.0e5
poisson_ratio = 0.45
thickness_m = 0.001
density_kg_per_m3 = 1000.0
reference = "test"
[element]
bending = "dkt"
[[fix]]
node_set = "fixed"
dofs = ["x", "y", "z", "rx", "ry", "rz"]
[modal]
mode_count = 4
method = "auto"
damping_ratio = 0.05
time_step_s = 0.001
static_correction = true
surface_set = "surface"
EOF
}
write_liver() {
  cat >"$work/scene/models/liver.toml" <<EOF
[model]
name = "liver"
kind = "tet_tensor"
image = "liver.img"
[mesh]
generator = "gmsh"
file = "$work/$1.msh"
[material]
young_modulus_pa = 1.5e4
poisson_ratio = 0.45
density_kg_per_m3 = 1060.0
reference = "test"
[[fix]]
node_set = "fixed"
dofs = ["x", "y", "z"]
[tensor]
contact_set = "surface"
stored = "surface"
max_contacts = 2
time_step_s = 0.001
EOF
}
run_build() {
  local scene=$1 case=$2
  shift 2
  local status=0
  "$modelc" build --scene "$work/scene/scenes/$scene.toml" --only "$scene" \
    >"$work/build_$case.out" 2>&1 || status=$?
  check "build $scene/$case" "$status" "$work/build_$case.out" "$@"
}
write_duct shell_good
run_build duct shell_good accepted
write_duct shell_sliver
run_build duct shell_sliver "model 'duct': invalid shell mesh: triangle 0 (nodes 0, 1, 4): sliver"
write_liver tet_good
run_build liver tet_good accepted
write_liver tet_sliver
run_build liver tet_sliver "liver.toml: tet mesh: tetrahedron 0 (nodes 0, 1, 2, 3) is a sliver"

if [[ $failures -ne 0 ]]; then
  echo "$failures case(s) failed"
  exit 1
fi
