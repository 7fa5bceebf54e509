"""``vebuild demo``: the whole pipeline on the bundled example room, checked against its truth:
calibration (paper §2), then the model solved with re-calibration (§3.1–3.2), then its textures
extracted from the photos (§4), then its named views rendered under each lighting preset and each
photo's camera rendered over its photo (§5).

The example (scenes/room) was rendered from a known scene by a generator independent of vebuild,
with the marks a careful user would make (0.7 px noise). Like real photographs, one (p6) was taken
through a wide lens with barrel distortion, and one camera (p4's) records a nominal focal length in
EXIF, 2.5 % short. The demo copies it to a folder of the user's, runs every stage vebuild has, and
prints the results next to the ground truth: the cameras, the lens distortion recovered, what the
EXIF focal lengths say against the truth, the model, the textures.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np

from vebuild.camera import log_so3
from vebuild.console.bars import Bar
from vebuild.console.progress import progress_bar
from vebuild.console.tables import calibration_table, model_table, texture_table
from vebuild.errors import VebuildError
from vebuild.project import load_project, save_project
from vebuild.project.decode import camera_records
from vebuild.resources import example_project_dir

from .calibrate import calibrate_project
from .demo_summary import check_explanations, summary
from .solve import solve_project
from .texture import texture_project

PROJECT_NAME = "room.vebuild.json"
#: zlib's level for the demo's renders: the same pixels as the default's, written some four times
#: faster (its PNGs a quarter larger).
PNG_COMPRESS_LEVEL = 1


def copy_example(out: Path) -> Path:
    """Copy the example project into ``out`` and return its project file.

    ``out`` must be new, empty, or a demo folder vebuild wrote that nobody changed since (its
    manifest lists every file with its SHA-256; :func:`vebuild.project.outputs.check_folder`): a project
    the user went on to edit there, or any other file, is never overwritten. The copy is made
    beside ``out`` and renamed into place whole.
    """
    from vebuild.project.atomic import clean_stale, remove_tree, replace_folder, temp_path
    from vebuild.project.outputs import check_folder, write_manifest

    out = Path(out)
    if out.parent.is_dir():
        clean_stale(out.parent)
    check_folder(None, out, "demo")
    if not out.parent.is_dir():
        raise VebuildError(f"{out}: the folder {out.parent} does not exist; create it first or choose another --out")
    tmp = temp_path(out)
    try:
        shutil.copytree(example_project_dir(), tmp)
        write_manifest(tmp, "demo")
        replace_folder(tmp, out)
    except OSError as e:
        remove_tree(tmp)
        raise VebuildError(f"{out}: cannot copy the example there ({e.strerror or e})") from None
    return out / PROJECT_NAME


def truth_comparison(result: dict, truth: dict) -> str:
    """Errors of the calibrated cameras against the example's known cameras, with |error|/σ."""
    lines = ["comparison with the ground truth (error, and error / reported 1σ):",
             f"  {'photo':<6}{'mode':<6}{'focal':>16}{'rotation':>16}{'position':>22}"]
    for pid, cam in result["cameras"].items():
        t = truth["photos"][pid]
        f_t = t["K"][0][0]
        df = (cam["focal_px"]["value"] - f_t) / f_t
        zf = abs(cam["focal_px"]["value"] - f_t) / cam["focal_px"]["sigma"]
        rot = np.degrees(np.linalg.norm(log_so3(np.asarray(t["R"]) @ np.asarray(cam["R"]).T)))
        dC = np.asarray(cam["position"]["value"]) - np.asarray(t["C"])
        zC = np.max(np.abs(dC) / np.asarray(cam["position"]["sigma"]))
        lines.append(f"  {pid:<6}{cam.get('mode', ''):<6}{100 * df:>+9.2f} % ({zf:.1f}σ){rot:>9.3f}°      "
                     f"{100 * np.linalg.norm(dC):>8.1f} cm (max {zC:.1f}σ)")
    return "\n".join(lines)


def distortion_comparison(cameras: dict, truth: dict) -> str:
    """Each photo's lens distortion as calibrated (the division model's k1 ± 1σ, and how far it
    moves the farthest corner) against the true lens's; a photo without a distortion record is
    taken as a pinhole, as is one that holds k1 = 0 exactly."""
    from .example_truth import true_corner_displacement_px, true_k1

    lines = ["lens distortion against the ground truth (division model k1; how far the lens moves the "
             "farthest corner):"]
    pinholes = []
    for pid, cam in cameras.items():
        t = truth["photos"][pid]
        k1_t, corner_t = true_k1(t), true_corner_displacement_px(t)
        d = cam.get("distortion")
        if d is None or (d["k1"]["value"] == 0.0 and not d["k1"]["sigma"]):  # none, or k1 = 0 held: a pinhole
            if k1_t == 0.0:
                pinholes.append(pid)
            else:
                lines.append(f"  {pid:<6}taken as a pinhole; the true lens has k1 {k1_t:+.4f}, moving its corners "
                             f"{corner_t:.1f} px")
            continue
        k1, s = d["k1"]["value"], d["k1"]["sigma"]
        corner, cs = d["corner_displacement_px"]["value"], d["corner_displacement_px"]["sigma"]
        z = f"{abs(k1 - k1_t) / s:.1f}σ" if s > 0 else "held"
        share = f", {100 * (corner - corner_t) / corner_t:+.0f} % of it" if corner_t > 0 else ""
        lines.append(f"  {pid:<6}k1 {k1:+.4f} ± {s:.4f} (true {k1_t:+.4f}: {z}); corners moved {corner:.1f} ± "
                     f"{cs:.1f} px (true {corner_t:.1f} px: {corner - corner_t:+.1f} px{share})")
    if pinholes:
        lines.append(f"  {', '.join(pinholes)}: pinholes (no distortion estimated), as their lenses truly are")
    return "\n".join(lines)


def exif_comparison(cameras: dict, photos: list[dict], truth: dict) -> str:
    """For each photo whose EXIF focal length is off the truth (p4's camera records a nominal one),
    the EXIF value and the calibrated focal length against the true f: how far EXIF misled, and
    whether the calibration's interval holds the truth."""
    from .example_truth import true_exif_error_rel

    lines = ["EXIF focal lengths against the ground truth:"]
    exact = []
    for photo in photos:
        pid, f_exif = photo["id"], (photo.get("exif") or {}).get("focal_length_px")
        if f_exif is None or pid not in cameras:
            continue
        t = truth["photos"][pid]
        if true_exif_error_rel(t) == 0.0:
            exact.append(pid)
            continue
        f_t = t["K"][0][0]
        cam = cameras[pid]
        f, s = cam["focal_px"]["value"], cam["focal_px"]["sigma"]
        source = str(cam.get("focal_source", "?")).split(":")[0]  # "exif: 1.46 mm × …": the kind only
        how = "re-calibrated" if cam.get("recalibrated") else f"calibrated (f from {source})"
        lines.append(f"  {pid:<6}EXIF says f = {f_exif:.1f} px, {100 * (f_exif / f_t - 1):+.2f} % off the true "
                     f"{f_t:.1f} px; {how}: {f:.1f} ± {s:.1f} px ({100 * (f / f_t - 1):+.2f} %, "
                     f"{abs(f - f_t) / s:.1f}σ from the truth; EXIF {100 * (f_exif / f - 1):+.2f} % from it)")
    if exact:
        lines.append(f"  {', '.join(exact)}: EXIF exact (the calibration table's EXIF check shows how close)")
    return "\n".join(lines)


def run_demo(out: Path, progress: bool = True) -> int:
    """Copy the example, calibrate it, save it, and print the results and their errors."""
    project_file = copy_example(out)
    print(f"example project copied to {out}/")
    project = load_project(project_file)
    result = calibrate_project(project, progress=lambda it: Bar(it, desc="calibrating", unit="photo",
                                                                disable=not progress))
    save_project(project)
    print(calibration_table(result))
    truth_file = out / "ground_truth.json"
    truth = json.loads(truth_file.read_text()) if truth_file.exists() else None
    if truth:
        print()
        print(truth_comparison(result, truth))
        print()
        print(distortion_comparison(result["cameras"], truth))
        print()
        print(exif_comparison(result["cameras"], project.data["photos"], truth))
    print("\n" + "-" * 80 + "\nmodelling: fitting the primitives to the pins, re-calibrating the cameras with them\n")
    model = solve_project(project, recalibrate=True)
    save_project(project)
    print(model_table(model))
    if truth and "model" in truth:
        print()
        print(model_comparison(model, truth))
    if truth:
        recal = camera_records(project.data)  # re-calibrated: model_solution.cameras
        print("\nre-calibrated cameras:")
        print(truth_comparison({"cameras": recal}, truth))
        print()
        print(distortion_comparison(recal, truth))
        print()
        print(exif_comparison(recal, project.data["photos"], truth))
    print("\n" + "-" * 80 + "\ntexturing: ID buffers and texel projection on the GPU, weighted merge\n")
    with progress_bar(progress) as step:
        record, textures = texture_project(project, progress=step)  # saves the project with its pages
    print(texture_table(record))
    if truth:
        print()
        print(texture_comparison(project, textures, truth))
    print("\n" + "-" * 80 + "\nrendering: the named views, and each photo's camera against its photo\n")
    print(render_views(project, out / "renders"))
    print(f"\nresults written to {project_file}; textures in {out / 'textures'}; renders in {out / 'renders'}")
    seen = sum(1 for f in record["faces"] if f["seen_fraction"] > 0)
    why = check_explanations(project, model.get("check_distances") or [], truth) if truth else []
    if why:  # just above the summary, which points to it: the last screen says it
        print("\n" + "\n".join(why))
    print("\n" + summary(project, model, truth, out, seen))
    from vebuild.project.outputs import write_manifest

    write_manifest(out, "demo")  # so that a later demo may replace this folder, unless someone changes it
    return 0


def render_views(project, folder: Path) -> str:
    """Every named view (as photographed and under each lighting preset) to PNG, and each photo's
    camera overlaid on its photo with the RMS colour difference."""
    from vebuild.render.scene import load_scene

    from .render import RenderRequest, render_evidence

    folder.mkdir(exist_ok=True)
    scene = load_scene(project)  # the pages and coverage maps decoded once for every render
    lines = []
    presets = [None] + [p["name"] for p in (project.data.get("lighting") or {}).get("presets", [])]
    for view in project.data.get("views", []):
        for preset in presets:
            stem = "_".join((view["name"] + ("-" + preset if preset else "")).replace(",", "").split())
            res = render_evidence(project, RenderRequest(out=folder / f"{stem}.png", view=view["name"],
                                                         lighting=preset, png_compress_level=PNG_COMPRESS_LEVEL),
                                  scene)
            lines.append(f"  {res.out.relative_to(folder.parent)}")
    lines.append("  how well the model explains each photo (RMS colour difference where the model covers it):")
    for photo in project.data["photos"]:
        if photo["id"] not in (project.data.get("calibration") or {}).get("cameras", {}):
            continue
        res = render_evidence(project, RenderRequest(out=folder / f"photo-{photo['id']}.png", photo=photo["id"],
                                                     validate=True, png_compress_level=PNG_COMPRESS_LEVEL), scene)
        assert res.rms_colour_difference is not None and res.covered_fraction is not None and res.overlay is not None
        lines.append(f"    {photo['id']}: {res.rms_colour_difference:5.1f} sRGB levels over "
                     f"{100 * res.covered_fraction:.0f} % of the photo (overlay: "
                     f"{res.overlay.relative_to(folder.parent)})")
    return "\n".join(lines)


def texture_comparison(project, textures, truth: dict) -> str:
    """Gains against the photos' true exposures; PSNR of the textures against the true ones."""
    from .example_truth import PSNR_SAMPLE_EVERY, texture_psnr

    first = truth["photos"][textures.order[0]]["exposure"]
    lines = ["comparison with the ground truth:",
             "  exposure gain (relative to " + textures.order[0] + "): " + ", ".join(
                 f"{pid} {g[0]:.3f} (true {truth['photos'][pid]['exposure'] / first:.3f})"
                 for pid, g in textures.gains.items())]
    try:
        from vebuild.project.decode import load_model

        model, _, _ = load_model(project)
        value = texture_psnr(model, textures, {p: v["exposure"] for p, v in truth["photos"].items()},
                             PSNR_SAMPLE_EVERY)
        lines.append(f"  PSNR of the textures against the true textures, over texels a photo saw: {value:.1f} dB "
                     f"(from every {PSNR_SAMPLE_EVERY}th texel)")
    except FileNotFoundError:  # the scene generator is not installed alongside: no true textures
        pass
    return "\n".join(lines)


def model_comparison(result: dict, truth: dict) -> str:
    """Each solved dimension against the example's true one, with |error| / reported 1σ."""
    true_nodes = {n["name"]: n for n in truth["model"]["nodes"]}
    lines = ["comparison with the ground truth (dimensions, mm):"]
    for name, node in result["nodes"].items():
        parts = []
        for k, v in node["params"].items():
            tv = true_nodes[name]["primitive"]["params"][k]
            err = v["value"] - tv
            z = f" ({abs(err) / v['sigma']:.1f}σ)" if v["sigma"] else " (held)"
            parts.append(f"{k} {1000 * err:+.1f}{z}")
        if parts:
            lines.append(f"  {name:<12} " + ", ".join(parts))
    return "\n".join(lines)
