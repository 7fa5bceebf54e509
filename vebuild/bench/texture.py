"""``vebuild bench texture``: speed, memory and quality of texture extraction (paper §4).

Speed (run it alone: other work on the machine distorts it): 12-megapixel JPEG photos (the
example room's five photos enlarged 2.5× with mild sensor noise, JPEG quality 92, each used four
times for 20 photos) of the example room's true model with nine more boxes (103 faces). Per photo:
read + hash, decode, upload, pyramid, ID pass, texel pass (including the exposure statistics),
the best-weight pre-pass, and the merge (once, divided by the number of photos), each timed in a
run that waits for the GPU after every stage; the total is the wall time of a second, unwaited
run (the GPU then finishes one photo while the next is decoded). The references, in the same
process: decoding the same JPEG alone (the floor: a photo must be decoded once) and the numpy CPU
reference of passes 1–2 (:mod:`vebuild.texture.reference`) on the same photos.

Lens distortion: the same 20 (or 5) photos given a barrel lens (``LENS_K1``, moving the corners
of the 4000 × 3000 photos a few per cent: ``lens_corner_displacement_px``): the texel pass then
distorts every texel's pixel and footprint, and the ID buffer covers the photo's undistorted
bounds (``lens_cover_growth`` times the photo's pixels). Runs with and without the lens are
taken in turns, ``LENS_REPEATS`` of each, every stage waited for; ``lens_*_ms_per_photo`` and
``lens_pinhole_*_ms_per_photo`` are each stage's least time, ``lens_*_over_pinhole`` their ratios
(``passes``: the ID, texel and best-weight passes together; ``total``: the whole extraction). The photos' pixels are the
pinhole ones: what is timed does not depend on them.

Atlas: the faces no photo can see get token charts (:mod:`vebuild.texture.visibility`):
``token_chart_count`` of them, the atlas ``atlas_texels`` (gutters included) against
``atlas_texels_full_charts``, its size had they kept their full charts (the same layout, packed
without the test), and ``visibility_ms_per_photo`` the test's cost; likewise on the example room
(``room_*``).

Memory: peak resident memory of the process during an extraction (Linux VmHWM, reset before each
run) for 5 and 20 photos, and for 20 photos at twice the density (four times the texels).

Quality: on the example room at its true geometry and cameras, the PSNR of the extracted textures
against the true textures (averaged over each texel's square) over texels some photo saw, with
every improvement on, and with each switched off in turn (``seen_texel_share``: of the atlas's
on-face texels, which token charts make larger); also from the solved model and cameras
(``vebuild calibrate`` + ``solve --recalibrate`` on the noisy marks).
"""

from __future__ import annotations

import dataclasses
import io
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from vebuild.actions import example_truth as truth
from vebuild.camera import ImageCamera, Lens, distortion_displacement_px
from vebuild.console.bars import Bar
from vebuild.gl.context import headless_context, renderer_name
from vebuild.model.scene import Model, model_from_dict
from vebuild.project import sha256_file
from vebuild.texture import layout as lay
from vebuild.texture.extract import PhotoSource, extract
from vebuild.texture.lens import cover_growth
from vebuild.texture.merge import unseen_texels
from vebuild.texture.options import Options
from vebuild.texture.timings import Timings

GOALS = {"total_over_decode": 2.0, "speedup_over_cpu_reference": 10.0, "psnr_db": 30.0}
SCALE = 2.5  # 1600×1200 → 4000×3000 = 12 megapixels
NOISE_SIGMA = 2.0  # 8-bit levels of added sensor noise, so that the JPEGs are not unnaturally smooth
EXTRA_BOXES = 9
STAGES = ("read", "hash", "decode", "upload", "pyramid", "id_pass", "texel_pass")
#: Runs with and without the lens, taken in turns, for their ratios (the least time of each).
LENS_REPEATS = 3
#: The stages the lens changes: the ID pass covers more pixels, the texel passes distort.
LENS_STAGES = ("id_pass", "texel_pass", "best_weight")
#: The benchmark's lens (division model): barrel distortion of a wide lens, a few per cent at the
#: photos' corners.
LENS_K1 = -0.08


def bench_model(extra_boxes: int = EXTRA_BOXES) -> Model:
    """The true room model plus small boxes on the floor (6 faces each)."""
    gt = truth.ground_truth()
    nodes = list(gt["model"]["nodes"])
    rng = np.random.default_rng(7)
    for k in range(extra_boxes):
        nodes.append({"name": f"extra{k}", "parent": "floor",
                      "primitive": {"type": "box", "params": {"width": 0.2, "depth": 0.15, "height": 0.1}},
                      "joint": {"type": "rests_on", "face": "top",
                                "position": [float(rng.uniform(-2.2, 2.2)), float(rng.uniform(-1.8, 1.8))],
                                "yaw_deg": float(rng.uniform(0, 90))}})
    markers = {k: np.asarray(v, float) for k, v in gt["markers"].items()}
    return model_from_dict(nodes, markers)


def make_photos(folder: Path, scale: float, n_photos: int) -> tuple[list[ImageCamera], dict[str, PhotoSource]]:
    """Enlarged example photos as JPEGs in ``folder``, with their cameras."""
    rng = np.random.default_rng(11)
    base = truth.true_cameras()
    cams, sources, hashes = [], {}, {}
    for cam in base:
        img = Image.open(truth.photo_path(cam.id)).convert("RGB")
        w, h = round(cam.width * scale), round(cam.height * scale)
        big = np.asarray(img.resize((w, h), Image.Resampling.BICUBIC), np.float32)
        big = np.clip(big + rng.normal(0, NOISE_SIGMA, big.shape), 0, 255).astype(np.uint8)
        Image.fromarray(big).save(folder / f"{cam.id}.jpg", quality=92)
        hashes[cam.id] = sha256_file(folder / f"{cam.id}.jpg")
    for k in range(n_photos):
        cam = base[k % len(base)]
        s = cam.scaled(scale)
        pid = f"{cam.id}_{k}"
        cams.append(ImageCamera(pid, s.K, s.R, s.C, s.width, s.height))
        sources[pid] = PhotoSource(pid, folder / f"{cam.id}.jpg", hashes[cam.id])
    return cams, sources


def _reset_peak() -> bool:
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def _peak_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def speed(n_photos: int, progress: bool) -> dict[str, Any]:
    model = bench_model()
    fig: dict[str, Any] = {"photos": n_photos, "photo_megapixels": 0.0}
    with tempfile.TemporaryDirectory(prefix="vebuild-bench-texture-") as tmp:
        cams, sources = make_photos(Path(tmp), SCALE, n_photos)
        fig["photo_megapixels"] = cams[0].width * cams[0].height / 1e6
        fig["jpeg_mb_mean"] = float(np.mean([p.stat().st_size for p in Path(tmp).glob("*.jpg")]) / 1e6)
        opts = Options()
        # Warm up: compile the shaders, make the context.
        extract(model, cams[:1], sources, opts)
        bar = Bar(total=2 * n_photos, desc="bench texture: GPU", unit="photo", disable=not progress)
        # The split: every stage waits for the GPU before its clock stops.
        timings = Timings()
        res = extract(model, cams, sources, opts, progress=lambda k, n, _: bar.update(1 if k else 0),
                      timings=timings)
        # The total: the pipeline as it runs for users (the GPU finishes a photo while the next
        # one is decoded).
        t0 = time.perf_counter()
        extract(model, cams, sources, opts, progress=lambda k, n, _: bar.update(1 if k else 0))
        total = time.perf_counter() - t0
        bar.close()
        fig["faces"] = len(res.faces)
        fig["atlas_texels_millions"] = sum(a.shape[0] * a.shape[1] for a in res.atlases) / 1e6
        fig.update(atlas_figures(model, res, opts))
        for st in (*STAGES, "visibility", "best_weight", "merge"):
            fig[f"{st}_ms_per_photo"] = 1e3 * timings.seconds.get(st, 0.0) / n_photos
        fig["total_ms_per_photo"] = 1e3 * total / n_photos
        # The same photos through a lens.
        lens = [dataclasses.replace(c, lens=Lens(LENS_K1)) for c in cams]
        fig["lens_k1"] = LENS_K1
        fig["lens_corner_displacement_px"] = distortion_displacement_px(lens[0].K, lens[0].width, lens[0].height,
                                                                        Lens(LENS_K1))
        fig["lens_cover_growth"] = cover_growth(lens[0])
        # Pinhole and lens runs in turns, each stage's least time over LENS_REPEATS runs (a run is
        # slowed, never sped up, by other work on the machine), every stage waited for.
        best: dict[str, dict[str, float]] = {"pinhole": {}, "lens": {}}
        for _ in range(LENS_REPEATS):
            for name, cs in (("pinhole", cams), ("lens", lens)):
                split = Timings()
                t0 = time.perf_counter()
                extract(model, cs, sources, opts, timings=split)
                got = {st: split.seconds.get(st, 0.0) for st in LENS_STAGES}
                got["total"] = time.perf_counter() - t0
                got["passes"] = sum(got[st] for st in LENS_STAGES)
                for k, v in got.items():
                    best[name][k] = min(best[name].get(k, np.inf), v)
        for name, key in (("pinhole", "lens_pinhole"), ("lens", "lens")):
            for k, v in best[name].items():
                fig[f"{key}_{k}_ms_per_photo"] = 1e3 * v / n_photos
        for k in (*LENS_STAGES, "passes", "total"):
            fig[f"lens_{k}_over_pinhole"] = best["lens"][k] / max(best["pinhole"][k], 1e-12)
        # The floor: the same JPEGs decoded alone, the way vebuild decodes them.
        dec = []
        for cam in cams:
            data = sources[cam.id].path.read_bytes()
            t = time.perf_counter()
            with Image.open(io.BytesIO(data)) as img:
                np.asarray(img.convert("RGB") if img.mode != "RGB" else img)
            dec.append(time.perf_counter() - t)
        fig["jpeg_decode_alone_ms"] = 1e3 * float(np.median(dec))
        fig["total_over_decode"] = fig["total_ms_per_photo"] / fig["jpeg_decode_alone_ms"]
        # The CPU reference on the first photos (it is slow: a few suffice for a per-photo time).
        from vebuild.texture import reference

        n_ref = 1 if n_photos <= 5 else 2
        faces = res.faces
        mesh = lay.scene_mesh(model, faces)
        pix = [np.asarray(Image.open(sources[c.id].path).convert("RGB")) for c in cams[:n_ref]]
        t = time.perf_counter()
        reference.accumulate(mesh, cams[:n_ref], iter(pix), opts, gains=None)
        fig["cpu_reference_ms_per_photo"] = 1e3 * (time.perf_counter() - t) / n_ref
        gpu_work = sum(timings.seconds.get(s, 0.0) for s in ("upload", "pyramid", "id_pass", "texel_pass",
                                                              "best_weight", "merge")) / n_photos
        fig["gpu_passes_ms_per_photo"] = 1e3 * gpu_work
        fig["speedup_over_cpu_reference"] = fig["cpu_reference_ms_per_photo"] / fig["gpu_passes_ms_per_photo"]
    return fig


def atlas_figures(model: Model, res: Any, opts: Options, prefix: str = "") -> dict[str, Any]:
    """The atlas with token charts against the one full charts would make (laid out alone)."""
    full = lay.page_sizes(lay.layout(model, opts.texels_per_metre, opts.max_face_texels, res.page_size))
    before = sum(w * h for w, h in full)
    return {f"{prefix}token_chart_count": len(res.token_faces), f"{prefix}atlas_texels": res.atlas_texels,
            f"{prefix}atlas_texels_full_charts": before,
            f"{prefix}atlas_share_of_full_charts": res.atlas_texels / max(1, before)}


def memory(progress: bool, quick: bool) -> dict[str, Any]:
    model = bench_model()
    fig: dict[str, Any] = {}
    if not _reset_peak():
        return {"peak_memory_note": "peak memory needs Linux /proc/self/clear_refs"}
    with tempfile.TemporaryDirectory(prefix="vebuild-bench-texture-") as tmp:
        scale = 1.0 if quick else SCALE
        cams, sources = make_photos(Path(tmp), scale, 20)
        runs = (("5_photos", 5, 200.0), ("20_photos", 20, 200.0), ("20_photos_4x_texels", 20, 400.0))
        for label, n, density in Bar(runs, desc="bench texture: memory", unit="run", disable=not progress):
            _reset_peak()
            before = _peak_mb()
            extract(model, cams[:n], sources, Options(texels_per_metre=density))
            fig[f"peak_rss_mb_{label}"] = _peak_mb()
            fig[f"baseline_rss_mb_{label}"] = before
        fig["memory_photos_scale"] = scale
    return fig


def quality(progress: bool, quick: bool) -> dict[str, Any]:
    model, cams = truth.true_model(), truth.true_cameras()
    sources = {c.id: PhotoSource(c.id, truth.photo_path(c.id)) for c in cams}
    exposures = truth.ground_truth()["photos"]
    variants = {"all": {}, "no_exposure": {"exposure": False}, "no_detail": {"detail_sharpness": 1.0},
                "no_drop": {"drop_ratio": 0.0}, "no_erode": {"erode_px": 0.0},
                "paper": {"exposure": False, "detail_sharpness": 1.0, "drop_ratio": 0.0, "erode_px": 0.0}}
    if quick:
        variants = {k: variants[k] for k in ("all", "paper")}
    fig: dict[str, Any] = {}
    for name, kw in Bar(variants.items(), desc="bench texture: quality", unit="variant", disable=not progress):
        got, res = _psnr(model, cams, sources, Options(**kw), exposures)
        fig.update({f"{k}_{name}": v for k, v in got.items()})
        if name == "all":
            fig.update(atlas_figures(model, res, Options(), "room_"))
    # The whole pipeline: calibrated and solved from the noisy marks.
    solved_model, solved_cams, solved_sources = _solved_example()
    if solved_model is not None:
        got, _ = _psnr(solved_model, solved_cams, solved_sources, Options(), exposures)
        fig.update({f"{k}_solved": v for k, v in got.items()})
    return fig


def _psnr(model, cams, sources, opts, exposures) -> tuple[dict[str, float], Any]:
    res = extract(model, cams, sources, opts)
    value = truth.texture_psnr(model, res, {p: v["exposure"] for p, v in exposures.items()})
    seen = sum(int((c[..., 3] > 0).sum() - unseen_texels(c).sum()) for c in res.coverage)
    on_face = sum(int((c[..., 3] > 0).sum()) for c in res.coverage)
    return {"psnr_db": value, "seen_texel_share": seen / max(1, on_face)}, res


def _solved_example() -> tuple[Model | None, list[ImageCamera], dict[str, PhotoSource]]:
    from vebuild.actions.calibrate import calibrate_project
    from vebuild.actions.solve import solve_project
    from vebuild.project import load_project
    from vebuild.project.decode import cameras, load_model

    tmp = Path(tempfile.mkdtemp(prefix="vebuild-bench-texture-"))
    try:
        shutil.copytree(truth.ROOM, tmp / "room")
        project = load_project(next((tmp / "room").glob("*.vebuild.json")))
        calibrate_project(project)
        solve_project(project, recalibrate=True)
        model, _, _ = load_model(project)
        cams = list(cameras(project).values())
        sources = {c.id: PhotoSource(c.id, truth.photo_path(c.id)) for c in cams}
        # The solved model's faces match the true model's one for one (same nodes, same order).
        return model, cams, sources
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    fig: dict[str, Any] = {"renderer": renderer_name(headless_context())}
    fig.update(speed(5 if quick else 20, progress))
    fig.update(memory(progress, quick))
    fig.update(quality(progress, quick))
    fig["goals_met"] = bool(fig["total_over_decode"] <= GOALS["total_over_decode"]
                            and fig["speedup_over_cpu_reference"] >= GOALS["speedup_over_cpu_reference"]
                            and fig["psnr_db_all"] >= GOALS["psnr_db"])
    return fig


def table(fig: dict[str, Any]) -> str:
    lines = [f"texture benchmark on {fig['renderer']}", "",
             f"{fig['photos']} photos of {fig['photo_megapixels']:.1f} MP (JPEG {fig['jpeg_mb_mean']:.1f} MB), "
             f"{fig['faces']} faces, atlas {fig['atlas_texels_millions']:.2f} M texels", "",
             f"{'per photo (ms)':<34}{'time':>10}"]
    for st in (*STAGES, "visibility", "best_weight", "merge"):
        lines.append(f"{'  ' + st.replace('_', ' '):<34}{fig.get(f'{st}_ms_per_photo', 0.0):>10.1f}")
    lines += [f"{'  total':<34}{fig['total_ms_per_photo']:>10.1f}",
              f"{'JPEG decode alone (reference)':<34}{fig['jpeg_decode_alone_ms']:>10.1f}",
              f"{'total / decode alone':<34}{fig['total_over_decode']:>10.2f}   (goal ≤ 2)",
              f"{'GPU passes per photo':<34}{fig['gpu_passes_ms_per_photo']:>10.1f}",
              f"{'CPU reference per photo':<34}{fig['cpu_reference_ms_per_photo']:>10.1f}",
              f"{'speed-up over the CPU reference':<34}{fig['speedup_over_cpu_reference']:>10.1f}   (goal ≥ 10)", ""]
    for prefix, what in (("", "bench model"), ("room_", "example room")):
        if f"{prefix}atlas_texels" in fig:
            lines.append(f"atlas ({what}): {fig[f'{prefix}token_chart_count']} faces no photo can see given token "
                         f"charts; {fig[f'{prefix}atlas_texels'] / 1e6:.2f} M texels against "
                         f"{fig[f'{prefix}atlas_texels_full_charts'] / 1e6:.2f} M with full charts "
                         f"({100 * fig[f'{prefix}atlas_share_of_full_charts']:.0f} %)")
    lines.append("")
    if "lens_total_ms_per_photo" in fig:
        lines += [f"through a lens (k1 = {fig['lens_k1']:g}, corners moved "
                  f"{fig['lens_corner_displacement_px']:.0f} px, ID buffer {fig['lens_cover_growth']:.3f}× the photo's "
                  f"pixels), least of {LENS_REPEATS} runs each:",
                  f"{'per photo (ms)':<34}{'pinhole':>10}{'lens':>10}{'ratio':>8}"]
        for k in (*LENS_STAGES, "passes", "total"):
            lines.append(f"{'  ' + k.replace('_', ' '):<34}{fig[f'lens_pinhole_{k}_ms_per_photo']:>10.1f}"
                         f"{fig[f'lens_{k}_ms_per_photo']:>10.1f}{fig[f'lens_{k}_over_pinhole']:>8.2f}")
        lines.append("")
    if "peak_rss_mb_5_photos" in fig:
        lines += [f"peak memory (MB, photos at scale {fig['memory_photos_scale']}): 5 photos "
                  f"{fig['peak_rss_mb_5_photos']:.0f}, 20 photos {fig['peak_rss_mb_20_photos']:.0f}, "
                  f"20 photos with 4× the texels {fig['peak_rss_mb_20_photos_4x_texels']:.0f}", ""]
    lines.append(f"{'quality on the example room':<34}{'PSNR (dB)':>10}{'seen':>8}")
    for k in sorted(k[len('psnr_db_'):] for k in fig if k.startswith("psnr_db_")):
        share = 100 * fig[f"seen_texel_share_{k}"]
        lines.append(f"{'  ' + k.replace('_', ' '):<34}{fig[f'psnr_db_{k}']:>10.2f}{share:>7.1f}%")
    lines.append(f"goals (total ≤ 2× decode, ≥ 10× the CPU reference, PSNR ≥ 30 dB): "
                 f"{'met' if fig['goals_met'] else 'NOT met'}")
    return "\n".join(lines)
