"""The line on mesh-file materials tlm does not render names the files that define them (stop 66, after h384):
"of the N mesh files" counted material files, so one OBJ naming two MTL libraries was "2 mesh files" and two OBJs
sharing one library "the mesh file"."""

from tlm.render.checks import material_warnings
from tlm.scenes.loader import load_scene

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
CAMERA = ("lights: [{type: point, position: [0.3, 0.3, 1], power: [10, 10, 10]}]\n"
          "camera: {eye: [0.5, 0.5, 3], target: [0.5, 0.5, 0], vfov: 40}\nresolution: [8, 8]\n")


def _mtl(path, name):
    path.write_text(f"newmtl {name}\nKd 0.5 0.5 0.5\nmap_Kd {name}.png\n")


def test_one_obj_with_two_libraries_names_both(tmp_path):
    _mtl(tmp_path / "a.mtl", "wood")
    _mtl(tmp_path / "b.mtl", "stone")
    (tmp_path / "t.obj").write_text("mtllib a.mtl b.mtl\n" + TRI + "usemtl wood\nf 1 2 3\nusemtl stone\nf 2 4 3\n")
    (tmp_path / "s.yaml").write_text("geometry: {mesh: t.obj}\n" + CAMERA)
    (line,) = material_warnings(load_scene(tmp_path / "s.yaml"))
    assert line.startswith("2 materials of 'a.mtl' and 'b.mtl' ('wood' and 'stone') use what tlm does not "
                           "render:"), line


def test_two_objs_sharing_a_library_name_it_once(tmp_path):
    (tmp_path / "shared.mtl").write_text("newmtl wood\nKd 0.5 0.5 0.5\nmap_Kd w.png\n"
                                         "newmtl stone\nKd 0.5 0.5 0.5\nmap_Kd s.png\n")
    for stem, name in (("a", "wood"), ("b", "stone")):
        (tmp_path / f"{stem}.obj").write_text(f"mtllib shared.mtl\n{TRI}usemtl {name}\nf 1 2 3\n")
    (tmp_path / "s.yaml").write_text("geometry: [{mesh: a.obj}, {mesh: b.obj, transform: {translate: [2, 0, 0]}}]\n"
                                     + CAMERA)
    (line,) = material_warnings(load_scene(tmp_path / "s.yaml"))
    assert line.startswith("2 materials of 'shared.mtl' ("), line


def test_past_three_files_the_rest_are_counted(tmp_path):
    names = ["m0", "m1", "m2", "m3", "m4"]
    geometry = []
    for i, name in enumerate(names):
        _mtl(tmp_path / f"{name}.mtl", name)
        (tmp_path / f"{name}.obj").write_text(f"mtllib {name}.mtl\n{TRI}usemtl {name}\nf 1 2 3\n")
        geometry.append(f"{{mesh: {name}.obj, transform: {{translate: [{2 * i}, 0, 0]}}}}")
    (tmp_path / "s.yaml").write_text(f"geometry: [{', '.join(geometry)}]\n" + CAMERA)
    (line,) = material_warnings(load_scene(tmp_path / "s.yaml"))
    assert line.startswith("5 materials of 'm0.mtl', 'm1.mtl', 'm2.mtl' and 2 more files ('m0', 'm1', 'm2' and 2 "
                           "more) use what tlm does not render: map_Kd;"), line
