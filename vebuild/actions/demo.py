"""``vebuild demo``: the whole pipeline on the bundled example room, checked against its truth:
calibration (paper §2), then the model solved with re-calibration (§3.1–3.2), then its textures
extracted from the photos (§4), then its named views rendered under each lighting preset and each
photo's camera rendered over its photo (§5).

The example (scenes/room) was rendered from a known scene by a generator independent of vebuild,
with the marks a careful user would make (0.7 px noise). The demo copies it to a folder of the
user's, runs every stage vebuild has, and prints the results next to the ground truth.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
from tqdm import tqdm

from ..camera import log_so3
from ..console.progress import progress_bar
from ..console.tables import calibration_table, model_table, texture_table
from ..errors import VebuildError
from ..project import load_project, save_project
from ..resources import example_project_dir
from .calibrate import calibrate_project
from .solve import solve_project
from .texture import texture_project

PROJECT_NAME = "room.vebuild.json"


def copy_example(out: Path) -> Path:
    """Copy the example project into ``out`` and return its project file.

    ``out`` must be new, empty, or a demo folder vebuild wrote that nobody changed since (its
    manifest lists every file with its SHA-256; :func:`vebuild.project.outputs.check_folder`): a project
    the user went on to edit there, or any other file, is never overwritten. The copy is made
    beside ``out`` and renamed into place whole.
    """
    from ..project.atomic import clean_stale, remove_tree, replace_folder, temp_path
    from ..project.outputs import check_folder, write_manifest

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
        lines.append(f"  {pid:<6}{cam['mode']:<6}{100 * df:>+9.2f} % ({zf:.1f}σ){rot:>9.3f}°      "
                     f"{100 * np.linalg.norm(dC):>8.1f} cm (max {zC:.1f}σ)")
    return "\n".join(lines)


def run_demo(out: Path, progress: bool = True) -> int:
    """Copy the example, calibrate it, save it, and print the results and their errors."""
    project_file = copy_example(out)
    print(f"example project copied to {out}/")
    project = load_project(project_file)
    result = calibrate_project(project, progress=lambda it: tqdm(it, desc="calibrating", unit="photo",
                                                                 disable=not progress))
    save_project(project)
    print(calibration_table(result))
    truth_file = out / "ground_truth.json"
    truth = json.loads(truth_file.read_text()) if truth_file.exists() else None
    if truth:
        print()
        print(truth_comparison(result, truth))
    print("\n" + "-" * 80 + "\nmodelling: fitting the primitives to the pins, re-calibrating the cameras with them\n")
    model = solve_project(project, recalibrate=True)
    save_project(project)
    print(model_table(model))
    if truth and "model" in truth:
        print()
        print(model_comparison(model, truth))
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
    from ..project.outputs import write_manifest

    write_manifest(out, "demo")  # so that a later demo may replace this folder, unless someone changes it
    return 0


def render_views(project, folder: Path) -> str:
    """Every named view (as photographed and under each lighting preset) to PNG, and each photo's
    camera overlaid on its photo with the RMS colour difference."""
    from .render import RenderRequest, render_evidence

    folder.mkdir(exist_ok=True)
    lines = []
    presets = [None] + [p["name"] for p in (project.data.get("lighting") or {}).get("presets", [])]
    for view in project.data.get("views", []):
        for preset in presets:
            stem = "_".join((view["name"] + ("-" + preset if preset else "")).replace(",", "").split())
            res = render_evidence(project, RenderRequest(out=folder / f"{stem}.png", view=view["name"],
                                                         lighting=preset))
            lines.append(f"  {res.out.relative_to(folder.parent)}")
    lines.append("  how well the model explains each photo (RMS colour difference where the model covers it):")
    for photo in project.data["photos"]:
        if photo["id"] not in (project.data.get("calibration") or {}).get("cameras", {}):
            continue
        res = render_evidence(project, RenderRequest(out=folder / f"photo-{photo['id']}.png", photo=photo["id"],
                                                     validate=True))
        assert res.rms_colour_difference is not None and res.covered_fraction is not None and res.overlay is not None
        lines.append(f"    {photo['id']}: {res.rms_colour_difference:5.1f} sRGB levels over "
                     f"{100 * res.covered_fraction:.0f} % of the photo (overlay: "
                     f"{res.overlay.relative_to(folder.parent)})")
    return "\n".join(lines)


def texture_comparison(project, textures, truth: dict) -> str:
    """Gains against the photos' true exposures; PSNR of the textures against the true ones."""
    from .example_truth import texture_psnr

    first = truth["photos"][textures.order[0]]["exposure"]
    lines = ["comparison with the ground truth:",
             "  exposure gain (relative to " + textures.order[0] + "): " + ", ".join(
                 f"{pid} {g[0]:.3f} (true {truth['photos'][pid]['exposure'] / first:.3f})"
                 for pid, g in textures.gains.items())]
    try:
        from ..project.decode import load_model

        model, _, _ = load_model(project)
        value = texture_psnr(model, textures, {p: v["exposure"] for p, v in truth["photos"].items()})
        lines.append(f"  PSNR of the textures against the true textures, over texels a photo saw: {value:.1f} dB")
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
