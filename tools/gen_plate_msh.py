#!/usr/bin/env python3
"""Writes the Gmsh MSH 4.1 ASCII meshes of the published shell benchmarks that
`modelc static` is checked against (docs/model-verification.md), so those fixtures are
reproducible from a few parameters. Python 3 standard library only.

  plate  clamped square plate under uniform pressure (Timoshenko & Woinowsky-Krieger):
         [0, a] x [0, a] in z = 0, N x N quads. Physical groups: "plate" (2-D, every
         triangle), "edges" (1-D, the whole boundary), "centre" (0-D, the node at (a/2, a/2)).
  roof   quarter of the Scordelis-Lo roof (MacNeal & Harder 1985): cylinder of radius R about
         the x axis, x in [0, L/2], angle phi from the crown (+z) towards +y in [0, 40 deg],
         point (x, R sin phi, R cos phi). Groups: "roof" (2-D), "diaphragm" (x = 0),
         "symmetry_x" (x = L/2), "crown" (phi = 0), "free_edge" (phi = 40 deg), each 1-D, and
         "free_edge_midspan" (0-D, x = L/2 on the free edge: where the reference is quoted).

Both use exactly the node positions and triangles of the project's generators
(make_rectangle_plate / make_cylindrical_panel with TrianglePattern::alternating): grid node
(i, j) is node tag 1 + j (N + 1) + i, quad (i, j) is split along (i, j)-(i+1, j+1) when i + j is
even and along the other diagonal otherwise, and each triangle is ordered so its normal points
along +z (plate) or away from the axis (roof). Every node sits in one node block on the surface
entity; coordinates are written with repr(), which round-trips the doubles exactly.

Usage:
  tools/gen_plate_msh.py plate --divisions 16 --side 1.0 --output clamped_plate_16.msh
  tools/gen_plate_msh.py roof --divisions 32 --output scordelis_lo_quarter_32.msh
"""

import argparse
import math
import sys


def grid_triangles(cells_i, cells_j, tag, position, outward):
    """Alternating split of a structured grid; returns a list of node-tag triples."""
    triangles = []
    for j in range(cells_j):
        for i in range(cells_i):
            n00, n10 = tag(i, j), tag(i + 1, j)
            n01, n11 = tag(i, j + 1), tag(i + 1, j + 1)
            if (i + j) % 2 == 0:
                pair = [(n00, n10, n11), (n00, n11, n01)]
            else:
                pair = [(n00, n10, n01), (n10, n11, n01)]
            for a, b, c in pair:
                pa, pb, pc = position[a], position[b], position[c]
                u = [pb[k] - pa[k] for k in range(3)]
                v = [pc[k] - pa[k] for k in range(3)]
                normal = [u[1] * v[2] - u[2] * v[1],
                          u[2] * v[0] - u[0] * v[2],
                          u[0] * v[1] - u[1] * v[0]]
                centroid = [(pa[k] + pb[k] + pc[k]) / 3.0 for k in range(3)]
                direction = outward(centroid)
                if sum(normal[k] * direction[k] for k in range(3)) < 0.0:
                    b, c = c, b
                triangles.append((a, b, c))
    return triangles


def write_msh(stream, position, triangles, surface_name, curves, points, title):
    """position: {tag: (x, y, z)}; curves: [(name, [node tags in order])] (open polylines,
    each its own entity and physical group); points: [(name, node tag)]."""
    names = [(0, name) for name, _ in points] + [(1, name) for name, _ in curves]
    names.append((2, surface_name))
    physical_tag = {name_dim: index + 1 for index, name_dim in enumerate(names)}

    def box(tags):
        xs = [position[t] for t in tags]
        low = [min(p[k] for p in xs) for k in range(3)]
        high = [max(p[k] for p in xs) for k in range(3)]
        return " ".join(repr(v) for v in low + high)

    out = stream.write
    out("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
    out("$Comment\n" + title + "\n$EndComment\n")
    out("$PhysicalNames\n%d\n" % len(names))
    for dimension, name in names:
        out('%d %d "%s"\n' % (dimension, physical_tag[(dimension, name)], name))
    out("$EndPhysicalNames\n")

    # Entities: one point per 0-D group, one curve per 1-D group, one surface.
    out("$Entities\n%d %d 1 0\n" % (len(points), len(curves)))
    for index, (name, tag) in enumerate(points):
        p = position[tag]
        out("%d %s %s %s 1 %d\n" % (index + 1, repr(p[0]), repr(p[1]), repr(p[2]),
                                    physical_tag[(0, name)]))
    for index, (name, tags) in enumerate(curves):
        out("%d %s 1 %d 0\n" % (index + 1, box(tags), physical_tag[(1, name)]))
    bounding = " ".join(str(c + 1) for c in range(len(curves)))
    out("1 %s 1 %d %d %s\n" % (box(list(position)), physical_tag[(2, surface_name)],
                                len(curves), bounding))
    out("$EndEntities\n")

    count = len(position)
    out("$Nodes\n1 %d 1 %d\n2 1 0 %d\n" % (count, count, count))
    for tag in sorted(position):
        out("%d\n" % tag)
    for tag in sorted(position):
        p = position[tag]
        out("%s %s %s\n" % (repr(p[0]), repr(p[1]), repr(p[2])))
    out("$EndNodes\n")

    element_count = len(points) + sum(len(t) - 1 for _, t in curves) + len(triangles)
    out("$Elements\n%d %d 1 %d\n" % (len(points) + len(curves) + 1, element_count,
                                      element_count))
    element = 1
    for index, (_, tag) in enumerate(points):
        out("0 %d 15 1\n%d %d\n" % (index + 1, element, tag))
        element += 1
    for index, (_, tags) in enumerate(curves):
        out("1 %d 1 %d\n" % (index + 1, len(tags) - 1))
        for a, b in zip(tags, tags[1:]):
            out("%d %d %d\n" % (element, a, b))
            element += 1
    out("2 1 2 %d\n" % len(triangles))
    for a, b, c in triangles:
        out("%d %d %d %d\n" % (element, a, b, c))
        element += 1
    out("$EndElements\n")


def plate(args, stream):
    n, side = args.divisions, args.side
    if n < 2 or n % 2 != 0 or not side > 0.0:
        sys.exit("plate: expected an even number of divisions >= 2 and a positive side")

    def tag(i, j):
        return 1 + j * (n + 1) + i

    position = {tag(i, j): (side * i / n, side * j / n, 0.0)
                for j in range(n + 1) for i in range(n + 1)}
    triangles = grid_triangles(n, n, tag, position, lambda c: (0.0, 0.0, 1.0))
    # The boundary as one closed loop, counter-clockwise from (0, 0).
    loop = ([tag(i, 0) for i in range(n)] + [tag(n, j) for j in range(n)] +
            [tag(i, n) for i in range(n, 0, -1)] + [tag(0, j) for j in range(n, -1, -1)])
    write_msh(stream, position, triangles, "plate", [("edges", loop)],
              [("centre", tag(n // 2, n // 2))],
              "clamped square plate, side %r m, %dx%d quads, alternating diagonals "
              "(tools/gen_plate_msh.py plate --divisions %d --side %r)" % (side, n, n, n, side))


def roof(args, stream):
    n = args.divisions
    radius, half_length = args.radius, args.half_length
    sweep = args.half_angle_deg * math.pi / 180.0  # as the C++ tests write it, to the bit
    if n < 1 or not radius > 0.0 or not half_length > 0.0 or not 0.0 < sweep < math.pi:
        sys.exit("roof: expected divisions >= 1, positive radius and length, 0 < angle < 180")

    def tag(i, j):
        return 1 + j * (n + 1) + i

    position = {}
    for j in range(n + 1):
        angle = 0.0 + sweep * j / n  # same expression as make_cylindrical_panel (start 0)
        for i in range(n + 1):
            position[tag(i, j)] = (half_length * i / n, radius * math.sin(angle),
                                   radius * math.cos(angle))
    triangles = grid_triangles(n, n, tag, position, lambda c: (0.0, c[1], c[2]))
    curves = [("diaphragm", [tag(0, j) for j in range(n + 1)]),
              ("symmetry_x", [tag(n, j) for j in range(n + 1)]),
              ("crown", [tag(i, 0) for i in range(n + 1)]),
              ("free_edge", [tag(i, n) for i in range(n + 1)])]
    write_msh(stream, position, triangles, "roof", curves,
              [("free_edge_midspan", tag(n, n))],
              "Scordelis-Lo roof quarter, R %r, half-length %r, %r deg, %dx%d quads, alternating "
              "diagonals (tools/gen_plate_msh.py roof --divisions %d)"
              % (radius, half_length, args.half_angle_deg, n, n, n))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    p = commands.add_parser("plate", help="clamped square plate")
    p.add_argument("--divisions", type=int, default=16, help="quads per side (even)")
    p.add_argument("--side", type=float, default=1.0, help="side length a (m)")
    p.add_argument("--output", required=True, help="file to write, - for stdout")
    r = commands.add_parser("roof", help="Scordelis-Lo roof, quarter model")
    r.add_argument("--divisions", type=int, default=32, help="quads each way")
    r.add_argument("--radius", type=float, default=25.0, help="R (m)")
    r.add_argument("--half-length", type=float, default=25.0, help="L/2 (m)")
    r.add_argument("--half-angle-deg", type=float, default=40.0, help="free edge angle (deg)")
    r.add_argument("--output", required=True, help="file to write, - for stdout")
    args = parser.parse_args()
    generate = plate if args.command == "plate" else roof
    if args.output == "-":
        generate(args, sys.stdout)
    else:
        with open(args.output, "w", encoding="ascii", newline="\n") as stream:
            generate(args, stream)


if __name__ == "__main__":
    main()
