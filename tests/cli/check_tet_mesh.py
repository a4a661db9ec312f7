"""Checks a directory's tetrahedral mesh (mesh_tet.vtu, .inp) against inclusions.json, with
numpy and meshio only: positive elements filling the box, each phase's volume within 1 % of the
exact one (spheres, cylinders, ellipsoids; the interphase shells of coated ones and the voids
of debonded spheres),
conforming (no two nodes at one position; every
element face shared by two elements or lying in a box face), every least dihedral angle at least
5 degrees and as report.json gives it (its estimated count within -40 % and +60 %), opposite faces carrying the same nodes within 1e-9 of the
box, and the face, edge and corner node sets of the .inp. The mesh's cell is the box moved to
report.json's cell_origin (mesh_tet.shift_cell); its face clearance, computed here from the
inclusions, is the report's and at least 0.05 (every face at least 5 % of an inclusion's least
size, or of a fibre's radius, from its extremes and rims: no thin caps). Second-order meshes
(10-node tetrahedra): the same of the corners, and each midside node at the middle of its edge,
in VTK's order in the .vtu, Abaqus's in the .inp and Gmsh's in the .msh (meshio reads the last in
VTK's).

usage: check_tet_mesh.py DIR [VOLUME_TOLERANCE [LEAST_ANGLE]]
  (relative volume error, default 0.01; least dihedral angle in degrees, default 5)
"""
import json, math, sys
import numpy as np
import meshio
d = sys.argv[1]
volume_tolerance = float(sys.argv[2]) if len(sys.argv) > 2 else 0.01
least_angle = float(sys.argv[3]) if len(sys.argv) > 3 else 5.0
incs = json.load(open(d + "/inclusions.json"))
L = incs["box"]["size"][0]
rep = json.load(open(d + "/report.json"))["mesh_tet"]
o = np.asarray(rep["cell_origin"], float)


def clearance(incs, o, L):
    """Least distance of a face to an inclusion's extremes (rims, steep end disks, shells' outer
    surfaces) per unit."""
    least = 1e300
    def dist(x, a, half=0.0):
        d = abs(x - o[a]) % L
        return max(0.0, min(d, L - d) - half)
    for i in incs["inclusions"]:
        c = np.asarray(i["center"], float)
        mods = i.get("modifiers", {})
        # A shell's or a debonding void's outer surface: the extremes moved out by t.
        t = mods.get("coating", 0.0) or mods.get("debond_gap", 0.0)
        for a in range(3):
            if i["shape"] == "sphere":
                r = i["radius"]
                least = min(least, dist(c[a] - r, a) / r, dist(c[a] + r, a) / r)
                if t > 0:
                    least = min(least, dist(c[a] - r - t, a) / (r + t),
                                dist(c[a] + r + t, a) / (r + t))
                if 0 < mods.get("debond_fraction", 0.0) < 1:
                    # A void's cone has its apex at the centre, and two rims (circles at r and
                    # r + gap): faces are kept off them.
                    least = min(least, dist(c[a], a) / r)
                    u = np.asarray(mods["debond_axis"], float)
                    cos_cap = 1 - 2 * mods["debond_fraction"]
                    sin_cap = math.sqrt(max(0.0, 1 - cos_cap ** 2))
                    across = math.sqrt(max(0.0, 1 - u[a] ** 2))
                    for rho in (r, r + t):
                        for side in (-1, 1):
                            least = min(least, dist(c[a] + rho * cos_cap * u[a]
                                                    + side * rho * sin_cap * across, a) / r)
            elif i["shape"] == "ellipsoid":
                A = np.asarray(i["rotation"]) * np.asarray(i["semi_axes"])[None, :]
                ext, unit = np.linalg.norm(A[a]), min(i["semi_axes"])
                least = min(least, dist(c[a] - ext, a) / unit, dist(c[a] + ext, a) / unit)
                if t > 0:  # the offset's extremes: the ellipsoid's moved out by t
                    least = min(least, dist(c[a] - ext - t, a) / (unit + t),
                                dist(c[a] + ext + t, a) / (unit + t))
            else:
                h = np.asarray(i["half_axis"], float)
                r = i["radius"]
                u = h / np.linalg.norm(h)
                half = r * math.sqrt(max(0.0, 1 - u[a] ** 2))
                for end in (c[a] - h[a], c[a] + h[a]):
                    least = min(least, dist(end - half, a) / r, dist(end + half, a) / r)
                    if t > 0:
                        least = min(least, dist(end - half - t, a) / (r + t),
                                    dist(end + half + t, a) / (r + t))
                    if abs(u[a]) >= math.cos(math.radians(20)):
                        least = min(least, dist(end, a, half) / r)
    return least


got = min(1.0, clearance(incs, o, L))  # the report caps it at 1
assert abs(got - rep["face_clearance"]) <= 1e-9, (got, rep["face_clearance"])
assert got >= 0.05, "face clearance %g" % got
m = meshio.read(d + "/mesh_tet.vtu")
pts = m.points
kind = "tetra10" if rep.get("order", 1) == 2 else "tetra"
assert list(m.cells_dict) == [kind], (list(m.cells_dict), rep.get("order"))
cells = m.cells_dict[kind]
tets = cells[:, :4]
phase = np.asarray(m.cell_data_dict["phase"][kind]).astype(int)
inp = meshio.read(d + "/mesh_tet.inp", file_format="abaqus")
assert len(inp.cells_dict[kind]) == len(tets), "the .inp and the .vtu differ in elements"
if kind == "tetra10":
    # Midside nodes at the middle of the edges (0,1), (1,2), (2,0), (0,3), (1,3), (2,3); the .inp
    # and the .msh give each element the same ten nodes in that order (meshio reorders the .msh's).
    for k, (a, b) in enumerate([(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]):
        gap = np.abs(pts[cells[:, 4 + k]] - 0.5 * (pts[cells[:, a]] + pts[cells[:, b]])).max()
        assert gap <= 1e-12 * L, "midside node %d off its edge's middle by %g" % (k, gap)
    msh = meshio.read(d + "/mesh_tet.msh")
    # (The files number the nodes alike: compare the rows of node numbers, and the nodes.)
    for other, name in ((inp, ".inp"), (msh, ".msh")):
        assert np.abs(other.points[:len(pts)] - pts).max() <= 1e-9 * L, name + ": nodes"
        q = np.concatenate([c.data for c in other.cells if c.type == kind])
        assert {tuple(x) for x in q} == {tuple(x) for x in cells}, name + ": the 10-node elements differ"
    assert len(np.unique(cells)) == len(pts), "a node no element uses"
# Volumes: positive, and per phase within 1 % of the exact ones.
P = pts[tets]
vol = np.einsum("ij,ij->i", P[:, 1] - P[:, 0], np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 0])) / 6
assert vol.min() > 0, "an element has volume %g" % vol.min()
# Interphase and void labels: after the cores (1..F), family by family, one for the family's
# shells when it has coated inclusions, then one for its voids when it has debonded ones.
families = len(incs["family_names"])
def has(f, key):
    return any(i["family"] == f and i.get("modifiers", {}).get(key, 0) > 0 for i in incs["inclusions"])
shell_label, void_label = {}, {}
label = families + 1
for f in range(families):
    if has(f, "coating"):
        shell_label[f], label = label, label + 1
    if has(f, "debond_fraction"):
        void_label[f], label = label, label + 1


def ellipsoid_shell(a, t):
    """The volume between an ellipsoid of semi-axes a and its offset by t (Steiner's formula,
    S t + M t^2 + 4 pi t^3 / 3, M the integral of the support function |a n| over the unit
    sphere, S = abc times that of |n / a|), by Gauss-Legendre in cos(theta) and the trapezoid
    rule in phi (exact for periodic integrands to round-off here)."""
    x, w = np.polynomial.legendre.leggauss(200)
    phi = np.linspace(0, 2 * math.pi, 400, endpoint=False)
    ct, ph = np.meshgrid(x, phi, indexing="ij")
    st = np.sqrt(1 - ct ** 2)
    n = np.stack([st * np.cos(ph), st * np.sin(ph), ct], axis=-1)
    weight = w[:, None] * (2 * math.pi / len(phi))
    S = np.prod(a) * np.sum(weight * np.linalg.norm(n / a, axis=-1))
    M = np.sum(weight * np.linalg.norm(n * a, axis=-1))
    return S * t + M * t ** 2 + 4 / 3 * math.pi * t ** 3


exact = {}
for i in incs["inclusions"]:
    t = i.get("modifiers", {}).get("coating", 0.0)
    if i["shape"] == "sphere":
        r = i["radius"]
        v, shell = 4 / 3 * math.pi * r ** 3, 4 / 3 * math.pi * ((r + t) ** 3 - r ** 3)
    elif i["shape"] == "cylinder":
        r, length = i["radius"], 2 * np.linalg.norm(i["half_axis"])
        v = math.pi * r ** 2 * length
        # The offset by t of a flat-ended cylinder: the mantle's shell, the end disks moved out,
        # and at each rim a quarter disk of radius t turned about the axis (Pappus).
        shell = (math.pi * ((r + t) ** 2 - r ** 2) * length + 2 * math.pi * r ** 2 * t
                 + 2 * (math.pi * t ** 2 / 4) * 2 * math.pi * (r + 4 * t / (3 * math.pi)))
    elif i["shape"] == "ellipsoid":
        a = np.asarray(i["semi_axes"], float)
        v = 4 / 3 * math.pi * np.prod(a)
        shell = ellipsoid_shell(a, t) if t > 0 else 0.0
    else:
        raise AssertionError("unexpected shape " + i["shape"])
    exact[i["family"] + 1] = exact.get(i["family"] + 1, 0.0) + v
    if t > 0:
        exact[shell_label[i["family"]]] = exact.get(shell_label[i["family"]], 0.0) + shell
    f, g = i.get("modifiers", {}).get("debond_fraction", 0.0), i.get("modifiers", {}).get("debond_gap", 0.0)
    if f > 0:  # the spherical shell between r and r + g, over the fraction f of the directions
        r = i["radius"]
        exact[void_label[i["family"]]] = (exact.get(void_label[i["family"]], 0.0)
                                         + f * 4 / 3 * math.pi * ((r + g) ** 3 - r ** 3))
exact[0] = L ** 3 - sum(exact.values())
for label, v in exact.items():
    got = vol[phase == label].sum()
    assert abs(got / v - 1) < volume_tolerance, "phase %d: volume %g, exact %g" % (label, got, v)
assert np.all(pts >= o - 1e-12) and np.all(pts <= o + L + 1e-12), "nodes outside the cell"
assert abs(vol.sum() / L ** 3 - 1) < 1e-9, "the elements do not fill the box: %g" % vol.sum()
# Conforming: no two nodes at one position, and every element face is shared by exactly two
# elements or lies in a box face (shared by one).
u = np.unique(np.round(pts / (1e-12 * L)).astype(np.int64), axis=0)
assert len(u) == len(pts), "%d nodes share a position" % (len(pts) - len(u))
faces = np.sort(np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]],
                                tets[:, [0, 1, 2]]]), axis=1)
f, count = np.unique(faces, axis=0, return_counts=True)
assert count.max() == 2, "a face shared by %d elements" % count.max()
single = f[count == 1]
on_plane = np.zeros(len(single), bool)
for a in range(3):
    for end in (0.0, L):
        on_plane |= np.all(np.abs(pts[single][:, :, a] - o[a] - end) <= 1e-9 * L, axis=1)
assert on_plane.all(), "%d faces inside the box belong to one element" % (~on_plane).sum()
# Least dihedral angle of every element.
least = np.full(len(tets), 180.0)
for i in range(4):
    for j in range(i + 1, 4):
        k, l = [x for x in range(4) if x not in (i, j)]
        e = P[:, j] - P[:, i]
        e /= np.linalg.norm(e, axis=1)[:, None]
        u = P[:, k] - P[:, i]; w = P[:, l] - P[:, i]
        u -= np.einsum("ij,ij->i", u, e)[:, None] * e
        w -= np.einsum("ij,ij->i", w, e)[:, None] * e
        c = np.einsum("ij,ij->i", u, w) / np.linalg.norm(u, axis=1) / np.linalg.norm(w, axis=1)
        least = np.minimum(least, np.degrees(np.arccos(np.clip(c, -1, 1))))
assert least.min() >= least_angle, "least dihedral angle %.2f degrees" % least.min()
assert rep["tetrahedra"] == len(tets)
# The estimate the memory check made before meshing follows the count (fitted within -15 % to
# +21 % on the benchmark's meshes).
ratio = rep["estimated_tetrahedra"] / len(tets)
assert 0.6 < ratio < 1.6, "estimated %d elements for %d" % (rep["estimated_tetrahedra"], len(tets))
assert rep["min_dihedral_degrees"]["below_5_degrees"] == np.count_nonzero(least < 5.0)
assert abs(rep["min_dihedral_degrees"]["min"] - least.min()) < 1e-6, (rep["min_dihedral_degrees"]["min"], least.min())
# Periodic: the nodes of each face, brought to the opposite one, are its nodes.
tol = 1e-9 * L
for a in range(3):
    lo = pts[np.abs(pts[:, a] - o[a]) <= tol]
    hi = pts[np.abs(pts[:, a] - o[a] - L) <= tol]
    assert len(lo) == len(hi) and len(lo) > 0, (a, len(lo), len(hi))
    others = [b for b in range(3) if b != a]
    key = lambda q: set(map(tuple, np.round(q[:, others] / tol).astype(np.int64)))
    klo, khi = key(lo), key(hi)
    # rounding may put a coordinate pair one step apart: compare nearest instead when sets differ
    if klo != khi:
        from scipy.spatial import cKDTree
        dist, _ = cKDTree(lo[:, others]).query(hi[:, others])
        assert dist.max() <= tol, "axis %d: a face node has no image (%g)" % (a, dist.max())
# The node sets of the faces and edges: as many on each side.
ps = inp.point_sets
for a in "XYZ":
    assert len(ps[a + "MIN"]) == len(ps[a + "MAX"]) > 0, a
for s in ("EDGE_Y0Z0", "EDGE_Y1Z1", "EDGE_X0Z1", "CORNER_X1Y1Z1", "CORNER_X0Y0Z0"):
    assert len(ps[s]) >= 1, s
print("tets %d, least dihedral %.2f, volumes within %g %%" % (len(tets), least.min(),
                                                             100 * volume_tolerance))
