"""Meshes: vertex lists + indices with normals; sphere levels of detail, the ships, the box, the line cube."""
from __future__ import annotations

import numpy as np
import pytest

from driftframe.framework import meshes


@pytest.mark.parametrize("level", [0, 1, 2, 3, 4])
def test_icosphere_vertices_lie_on_the_unit_sphere_with_normals_along_them(level):
    m = meshes.icosphere(level)
    np.testing.assert_allclose(np.linalg.norm(m.vertices, axis=1), 1.0, atol=1e-6)
    np.testing.assert_allclose(m.normals, m.vertices, atol=1e-6)
    assert m.mode == "triangles"
    assert m.primitive_count == 20 * 4 ** level


@pytest.mark.parametrize("level", [0, 2, 4])
def test_icosphere_is_a_closed_surface_wound_counter_clockwise_from_outside(level):
    m = meshes.icosphere(level)
    tris = m.indices.reshape(-1, 3)
    centroids = m.vertices[tris].mean(axis=1)
    assert (np.einsum("ij,ij->i", m.face_normals(), centroids) > 0).all()
    # closed and shared: Euler characteristic V - E + F = 2, every edge used by exactly two faces
    edges = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    assert (uses == 2).all()
    assert len(m.vertices) - len(uses) + len(tris) == 2


def test_sphere_lod_error_is_the_largest_gap_to_the_true_sphere():
    rng = np.random.default_rng(0)
    errors = []
    for m in meshes.sphere_lods():
        t = m.vertices.astype(np.float64)[m.indices.reshape(-1, 3)]
        # sample each face densely (barycentric), the gap is 1 - |p|
        w = rng.dirichlet([1, 1, 1], size=64)
        w = np.vstack([w, [[1 / 3, 1 / 3, 1 / 3]]])
        pts = np.einsum("sk,fkd->fsd", w, t)
        gap = 1.0 - np.linalg.norm(pts, axis=2).min()
        assert gap <= m.lod_error + 1e-7
        assert gap >= 0.97 * m.lod_error          # the face centre attains (almost) the bound
        errors.append(m.lod_error)
    # each level halves the edge length: the gap shrinks about 4x
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert ((ratios > 3.0) & (ratios < 4.5)).all(), ratios


def test_pyramid_nose_points_along_local_forward_and_its_centre_of_mass_is_the_origin():
    m = meshes.pyramid(length=2.0, width=1.2, height=0.5)
    v = m.vertices.astype(np.float64)
    nose = v[np.argmax(v[:, 2])]
    np.testing.assert_allclose(nose, [0.0, 0.0, 1.5], atol=1e-6)        # 3/4 of the length ahead
    np.testing.assert_allclose(v[:, 2].min(), -0.5, atol=1e-6)           # base 1/4 behind
    assert np.isclose(v[:, 0].max(), 0.6) and np.isclose(v[:, 1].max(), 0.25)
    tris = v[m.indices.reshape(-1, 3)]
    # volume centroid from signed tetrahedra (origin, a, b, c): zero for the centre of mass
    vol = np.einsum("ij,ij->i", tris[:, 0], np.cross(tris[:, 1], tris[:, 2])) / 6.0
    centroid = (vol[:, None] * tris.sum(axis=1) / 4.0).sum(axis=0) / vol.sum()
    np.testing.assert_allclose(centroid, 0.0, atol=1e-7)
    assert vol.sum() > 0                                                  # outward (CCW) winding
    # flat shading: every vertex normal is its face's unit normal
    fn = m.face_normals()
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    np.testing.assert_allclose(m.normals.reshape(-1, 3, 3), np.repeat(fn[:, None], 3, 1), atol=1e-6)


def edges_shared_twice(m):
    """True when every edge of the (flat-shaded) triangle list is used by exactly two faces, once each way."""
    v = np.round(m.vertices.astype(np.float64), 6)
    keys = {tuple(p): k for k, p in enumerate(map(tuple, v))}
    ids = np.array([keys[tuple(p)] for p in v])[m.indices].reshape(-1, 3)
    directed = {}
    for a, b, c in ids:
        for e in ((a, b), (b, c), (c, a)):
            directed[e] = directed.get(e, 0) + 1
    return all(n == 1 and directed.get((b, a)) == 1 for (a, b), n in directed.items())


def test_ship_hull_is_a_closed_outward_solid_centred_on_its_centre_of_mass_with_the_nose_forward():
    m = meshes.ship_hull()
    assert m.mode == "triangles" and m.primitive_count >= 48              # more than a wedge
    assert edges_shared_twice(m)                                           # closed, consistently wound
    vol, com = meshes.volume_centroid(m.vertices, m.indices)
    assert vol > 0                                                         # outward
    np.testing.assert_allclose(com, 0.0, atol=1e-6)
    v = m.vertices.astype(np.float64)
    nose = v[np.argmax(v[:, 2])]
    np.testing.assert_allclose(nose[0], 0.0, atol=1e-9)                   # on the centre line, ahead
    assert nose[2] > 1.5 and v[:, 2].min() > -1.0
    np.testing.assert_allclose([v[:, 0].min(), v[:, 0].max()], [-1.0, 1.0], atol=1e-6)   # 2 m across the wings
    # mirror-symmetric about x = 0: the mirrored vertex set is the same set
    a = np.round(v, 5)
    assert {tuple(p) for p in a} == {tuple(p) for p in a * [-1, 1, 1]}
    fn = m.face_normals()
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    np.testing.assert_allclose(m.normals.reshape(-1, 3, 3), np.repeat(fn[:, None], 3, 1), atol=1e-6)


def test_box_is_a_flat_shaded_cuboid_and_volume_centroid_finds_an_offset_solid():
    m = meshes.box(2.0, 0.5, 3.0)
    assert m.primitive_count == 12 and edges_shared_twice(m)
    np.testing.assert_allclose(m.vertices.min(axis=0), [-1.0, -0.25, -1.5])
    np.testing.assert_allclose(m.vertices.max(axis=0), [1.0, 0.25, 1.5])
    vol, com = meshes.volume_centroid(m.vertices, m.indices)
    assert vol == pytest.approx(3.0) and np.allclose(com, 0.0)
    # every normal is one of the six axis directions and points away from the centre
    n = m.normals.reshape(-1, 3, 3)[:, 0]
    centres = m.vertices.reshape(-1, 3, 3).mean(axis=1)
    assert (np.abs(n).max(axis=1) == 1.0).all() and (np.einsum("ij,ij->i", n, centres) > 0).all()
    # the same box moved: the centroid moves with it, the volume does not; recentre brings it back
    shifted = m.vertices + np.array([4.0, -1.0, 2.5], np.float32)
    vol2, com2 = meshes.volume_centroid(shifted, m.indices)
    assert vol2 == pytest.approx(3.0) and np.allclose(com2, [4.0, -1.0, 2.5], atol=1e-6)
    back = meshes.flat_shaded("moved", shifted, m.indices.reshape(-1, 3), recentre=True)
    np.testing.assert_allclose(meshes.volume_centroid(back.vertices, back.indices)[1], 0.0, atol=1e-6)
    # a tetrahedron off the origin: volume 1/6, centroid the mean of its corners
    wedge = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]])
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    vol3, com3 = meshes.volume_centroid(wedge, faces)
    assert vol3 == pytest.approx(1 / 6) and np.allclose(com3, 0.25)
    with pytest.raises(ValueError, match="encloses no volume"):
        meshes.volume_centroid(wedge, faces[:1])
    with pytest.raises(ValueError, match="sy must be a finite number > 0"):
        meshes.box(1.0, -1.0, 1.0)


def test_line_cube_is_the_twelve_edges_of_a_unit_cube():
    m = meshes.line_cube(1)
    assert m.mode == "lines" and m.primitive_count == 12
    np.testing.assert_allclose(np.abs(m.vertices), 0.5)
    seg = m.vertices[m.indices.reshape(-1, 2)]
    d = seg[:, 1] - seg[:, 0]
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)          # side 1
    assert ((np.abs(d) > 0.5).sum(axis=1) == 1).all()                    # each along one axis
    assert len({tuple(sorted(map(tuple, s))) for s in seg}) == 12        # no duplicates


def test_line_cube_grid_stays_on_the_faces():
    m = meshes.line_cube(4)
    assert m.primitive_count == 12 + 6 * 2 * 3
    seg = m.vertices[m.indices.reshape(-1, 2)]
    on_face = (np.isclose(np.abs(seg), 0.5)).sum(axis=2) >= 1           # every end point on a face
    assert on_face.all()
    mid = seg.mean(axis=1)
    assert (np.isclose(np.abs(mid), 0.5).any(axis=1)).all()             # and the whole segment too


def test_mesh_rejects_bad_vertex_and_index_lists():
    v = np.eye(3)
    with pytest.raises(ValueError, match=r"indices must be in \[0, 2\], got \[0, 3\]"):
        meshes.Mesh("bad", v, v, [0, 1, 3])
    with pytest.raises(ValueError, match="multiple of 3"):
        meshes.Mesh("bad", v, v, [0, 1])
    with pytest.raises(ValueError, match="finite"):
        meshes.Mesh("bad", [[np.nan, 0, 0], [0, 1, 0], [0, 0, 1]], v, [0, 1, 2])
    with pytest.raises(ValueError, match="mode must be one of"):
        meshes.Mesh("bad", v, v, [0, 1, 2], mode="strip")
    with pytest.raises(ValueError, match="level must be an int"):
        meshes.icosphere(-1)
    with pytest.raises(ValueError, match="width must be a finite number > 0"):
        meshes.pyramid(width=0.0)


def test_mesh_arrays_are_read_only_copies():
    v = np.eye(3, dtype=np.float32)
    m = meshes.Mesh("tri", v, v, [0, 1, 2])
    v[0, 0] = 5.0
    assert m.vertices[0, 0] == 1.0
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 2.0


# -- models from files (the 'assets' extra: trimesh) ------------------------------------------------
import os  # noqa: E402
import sys  # noqa: E402

# a square pyramid off the origin: base 2 x 2 at z = 0, apex 4 m up; its centre of mass is 1/4 of the way up,
# (not the vertex mean, z = 0.8, nor the box centre, z = 2)
OFFSET = np.array([5.0, -2.0, 3.0])
PYR_V = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0], [0, 0, 4.0]]) + OFFSET
PYR_F = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
PYR_COM = OFFSET + [0.0, 0.0, 1.0]


def need_trimesh():
    """trimesh, or a skip where the 'assets' extra is not installed (CI installs it: there a failure)."""
    if os.environ.get("CI"):
        import trimesh
        return trimesh
    return pytest.importorskip("trimesh", reason="the 'assets' extra (trimesh) is not installed")


def write_model(path, kind):
    """The pyramid written by this test: OBJ by hand, glTF and GLB with trimesh's exporters."""
    if kind == "obj":
        lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in PYR_V] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in PYR_F]
        path.write_text("# a pyramid\n" + "\n".join(lines) + "\n")
        return path
    trimesh = need_trimesh()
    mesh = trimesh.Trimesh(PYR_V, PYR_F, process=False)
    if kind == "glb":
        path.write_bytes(mesh.export(file_type="glb"))
    else:
        (name, data), = trimesh.exchange.gltf.export_gltf(mesh, embed_buffers=True).items()
        path.write_bytes(data)
    return path


@pytest.mark.parametrize("kind", ["obj", "gltf", "glb"])
def test_a_model_file_round_trips_recentred_on_its_centre_of_mass(tmp_path, kind):
    need_trimesh()
    m = meshes.load_mesh(write_model(tmp_path / f"pyramid.{kind}", kind), "pyr")
    assert m.name == "pyr" and m.mode == "triangles" and m.primitive_count == 6
    # the same corners, moved by minus the centre of mass (not the vertex mean, not the bounding-box centre)
    got = {tuple(p) for p in np.round(m.vertices.astype(np.float64), 5)}
    assert got == {tuple(p) for p in np.round(PYR_V - PYR_COM, 5)}
    vol, com = meshes.volume_centroid(m.vertices, m.indices)             # an independent check, without trimesh
    assert vol == pytest.approx(16.0 / 3.0, rel=1e-6)                      # outward winding kept: base 4 x height 4 / 3
    np.testing.assert_allclose(com, 0.0, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-5)
    flat = meshes.load_mesh(tmp_path / f"pyramid.{kind}", shading="flat")
    assert flat.name == "pyramid" and len(flat.vertices) == 18
    np.testing.assert_allclose(meshes.volume_centroid(flat.vertices, flat.indices)[1], 0.0, atol=1e-5)


def test_an_inside_out_closed_model_is_turned_the_right_way_and_still_centred(tmp_path):
    need_trimesh()
    p = tmp_path / "inside_out.obj"
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in PYR_V] + [f"f {a + 1} {c + 1} {b + 1}" for a, b, c in PYR_F]
    p.write_text("\n".join(lines) + "\n")
    m = meshes.load_mesh(p)
    vol, com = meshes.volume_centroid(m.vertices, m.indices)
    assert vol == pytest.approx(16.0 / 3.0, rel=1e-6)
    np.testing.assert_allclose(com, 0.0, atol=1e-5)


def test_missing_malformed_and_unknown_model_files_are_errors_that_name_the_file(tmp_path):
    need_trimesh()
    with pytest.raises(FileNotFoundError, match=r"model file '.*nowhere\.obj' not found"):
        meshes.load_mesh(tmp_path / "nowhere.obj")
    with pytest.raises(ValueError, match=r"model file '.*ship\.fbx': unknown type '\.fbx'; driftframe reads"):
        meshes.load_mesh(tmp_path / "ship.fbx")
    junk = tmp_path / "junk.obj"
    junk.write_text("this is not\nan OBJ file\n")
    with pytest.raises(ValueError, match=r"model file '.*junk\.obj' has no triangles"):
        meshes.load_mesh(junk)
    broken = tmp_path / "broken.glb"
    broken.write_bytes(write_model(tmp_path / "whole.glb", "glb").read_bytes()[:40])   # cut short
    with pytest.raises(ValueError, match=r"model file '.*broken\.glb' could not be read as GLB"):
        meshes.load_mesh(broken)
    folder = tmp_path / "dir.obj"
    folder.mkdir()
    with pytest.raises(FileNotFoundError, match=r"model file '.*dir\.obj' is not a file"):
        meshes.load_mesh(folder)


def test_without_trimesh_loading_says_which_extra_to_install(tmp_path, monkeypatch):
    p = write_model(tmp_path / "p.obj", "obj")
    monkeypatch.setitem(sys.modules, "trimesh", None)           # as if it were not installed
    with pytest.raises(ImportError, match=r"'.*p\.obj' needs trimesh, the 'assets' extra: pip install"):
        meshes.load_mesh(p)
