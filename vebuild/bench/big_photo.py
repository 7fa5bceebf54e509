"""Peak memory of decoding and texturing from one very large photo (a one-off measurement).

``python3 -m vebuild.bench.big_photo [--cases png,jpeg,raw] [--side SIDE] [--json OUT]`` measures,
each in a fresh process so that the peak is that run's alone:

* ``png``: a SIDE × SIDE PNG (default 10900: 119 MP, just under the 120 MP a project's photo may
  have; a 13000² photo, 169 MP, is refused before it is decoded), a smooth gradient that compresses
  to well under a megabyte, as a scan or a stitched panorama might;
* ``jpeg``: a 45-megapixel JPEG (8256 × 5504, a Nikon D850's size) with the grain of a real photo,
  so that it is a file of a camera's size (10.6 MB at quality 92);
* ``raw``: a camera RAW file of that size, a DNG of a 14-bit Bayer mosaic (tifffile writes it),
  developed by LibRaw.

For each: the decode alone (:func:`vebuild.project.images.decode_photo`, as every consumer reads a
photo) and the example room's texture extraction from it. Figures (``--json``) are named with their
unit: peak resident memory (Linux VmHWM) in MB, the same over the photo's decoded size (3 bytes a
pixel: the least any extraction must hold once), seconds.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

#: A Nikon D850's image: 45.7 megapixels.
SIZE_45MP = (8256, 5504)


def _peak_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def write_photo(path: Path, side: int) -> None:
    """A smooth colour gradient, SIDE × SIDE, as PNG (written row band by row band)."""
    img = Image.new("RGB", (side, side))
    band = 1024
    x = np.linspace(0.0, 1.0, side, dtype=np.float32)
    for y0 in range(0, side, band):
        y = np.linspace(y0 / side, min(side, y0 + band) / side, min(band, side - y0), dtype=np.float32)
        rgb = np.stack(np.broadcast_arrays(60 + 150 * x[None, :], 60 + 150 * y[:, None], 120 + 0 * x[None, :]),
                       axis=-1)
        img.paste(Image.fromarray(rgb.astype(np.uint8)), (0, y0))
    img.save(path, format="PNG", compress_level=9)


def _grainy_rows(w: int, y0: int, n: int, h: int, rng: np.random.Generator) -> np.ndarray:
    """Rows y0…y0+n of a gradient with a photo's grain (σ 6 levels), (n, w, 3) uint8."""
    x = np.linspace(0.0, 1.0, w, dtype=np.float32)
    y = (np.arange(y0, y0 + n, dtype=np.float32) / h)[:, None]
    base = np.stack(np.broadcast_arrays(60 + 150 * x[None, :], 60 + 150 * y, 120 + 40 * x[None, :] * y), axis=-1)
    return np.clip(base + rng.normal(0.0, 6.0, base.shape).astype(np.float32), 0, 255).astype(np.uint8)


def write_jpeg(path: Path, w: int, h: int) -> None:
    img = Image.new("RGB", (w, h))
    rng = np.random.default_rng(45)
    for y0 in range(0, h, 512):
        img.paste(Image.fromarray(_grainy_rows(w, y0, min(512, h - y0), h, rng)), (0, y0))
    img.save(path, format="JPEG", quality=92)


def write_dng(path: Path, w: int, h: int) -> None:
    """A DNG of a 14-bit RGGB mosaic of the grainy gradient (IFD0 holds the camera's EXIF)."""
    import tifffile

    rng = np.random.default_rng(46)
    cfa = np.empty((h, w), np.uint16)
    for y0 in range(0, h, 512):
        rgb = _grainy_rows(w, y0, min(512, h - y0), h, rng).astype(np.uint16) * 64
        rows = np.arange(y0, y0 + rgb.shape[0])[:, None] % 2
        cols = np.arange(w)[None, :] % 2
        channel = np.where(rows == 0, np.where(cols == 0, 0, 1), np.where(cols == 0, 1, 2))  # R G / G B
        cfa[y0:y0 + rgb.shape[0]] = np.take_along_axis(rgb, channel[..., None], axis=2)[..., 0]
    tags = [(50706, "B", 4, (1, 4, 0, 0), True), (50708, "s", 0, "vebuild bench camera", True),
            (33421, "H", 2, (2, 2), True), (33422, "B", 4, (0, 1, 1, 2), True), (50717, "I", 1, 16383, True),
            (50721, "2i", 9, (1000, 1000, 0, 1000, 0, 1000, 0, 1000, 1000, 1000, 0, 1000, 0, 1000, 0, 1000,
                              1000, 1000), True),
            (50778, "H", 1, 21, True), (271, "s", 0, "NIKON CORPORATION", True), (272, "s", 0, "NIKON D850", True)]
    tifffile.imwrite(path, cfa, photometric=32803, extratags=tags, subfiletype=0, metadata=None)


def child(photo: str, width: int, height: int, what: str) -> dict[str, float]:
    """Run in the fresh process: decode the photo (``what`` "decode") or extract the example
    room's textures from it alone ("extract"); its figures."""
    from vebuild.actions import example_truth as truth
    from vebuild.project import sha256_file
    from vebuild.project.images import decode_photo
    from vebuild.texture.extract import PhotoSource, extract
    from vebuild.texture.options import Options

    base = _peak_mb()
    t = time.perf_counter()
    if what == "decode":
        pixels = decode_photo(Path(photo).read_bytes(), photo, photo, "")
        assert pixels.shape == (height, width, 3), pixels.shape
        del pixels
    else:
        model, cams = truth.true_model(), truth.true_cameras()
        cam = cams[0].resized(width, height)
        src = PhotoSource(cam.id, Path(photo), sha256_file(Path(photo)))
        extract(model, [cam], {cam.id: src}, Options(texels_per_metre=200.0))
    return {"baseline_rss_mb": base, "peak_rss_mb": _peak_mb(), "seconds": time.perf_counter() - t}


def _run_child(photo: Path, w: int, h: int, what: str) -> dict[str, float]:
    out = subprocess.run([sys.executable, "-m", "vebuild.bench.big_photo", "--child", str(photo), str(w), str(h), what],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def measure(case: str, folder: Path, side: int, stages: tuple[str, ...] = ("decode", "extract")) -> dict[str, float]:
    """One case's figures (see the module docstring)."""
    w, h = (side, side) if case == "png" else SIZE_45MP
    photo = folder / {"png": "big.png", "jpeg": "big.jpg", "raw": "big.dng"}[case]
    {"png": lambda: write_photo(photo, side), "jpeg": lambda: write_jpeg(photo, w, h),
     "raw": lambda: write_dng(photo, w, h)}[case]()
    decoded_mb = 3 * w * h / 2**20
    fig: dict[str, float] = {"width_px": w, "height_px": h, "megapixels": w * h / 1e6,
                             "file_mb": photo.stat().st_size / 2**20, "decoded_mb": decoded_mb}
    for what in stages:
        r = _run_child(photo, w, h, what)
        fig[f"{what}_peak_rss_mb"] = r["peak_rss_mb"]
        fig[f"{what}_baseline_rss_mb"] = r["baseline_rss_mb"]
        fig[f"{what}_peak_over_decoded"] = r["peak_rss_mb"] / decoded_mb
        fig[f"{what}_seconds"] = r["seconds"]
    photo.unlink()
    return fig


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--child"]:
        print(json.dumps(child(argv[1], int(argv[2]), int(argv[3]), argv[4])))
        return 0
    p = argparse.ArgumentParser(prog="python3 -m vebuild.bench.big_photo", description=__doc__.split("\n\n")[0])
    p.add_argument("--cases", default="png,jpeg,raw", help="comma-separated: png, jpeg, raw (default all)")
    p.add_argument("--side", type=int, default=10900, help="the PNG's side in pixels (default 10900: 119 MP)")
    p.add_argument("--stages", default="decode,extract", help="comma-separated: decode, extract (default both)")
    p.add_argument("--json", type=Path, help="write the figures here")
    args = p.parse_args(argv)
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    stages = tuple(s.strip() for s in args.stages.split(",") if s.strip())
    bad = [c for c in cases if c not in ("png", "jpeg", "raw")] + [s for s in stages if s not in ("decode", "extract")]
    if bad:
        p.error(f"unknown case or stage: {', '.join(bad)}")
    figures = {}
    with tempfile.TemporaryDirectory(prefix="vebuild-big-photo-") as tmp:
        for case in cases:
            fig = figures[case] = measure(case, Path(tmp), args.side, stages)
            print(f"{case}: {fig['width_px']}×{fig['height_px']} ({fig['megapixels']:.1f} MP), file "
                  f"{fig['file_mb']:.1f} MB, decoded {fig['decoded_mb']:.0f} MB")
            for what in stages:
                print(f"  {what}: peak resident memory {fig[f'{what}_peak_rss_mb']:.0f} MB (before "
                      f"{fig[f'{what}_baseline_rss_mb']:.0f} MB), {fig[f'{what}_peak_over_decoded']:.2f}× the decoded "
                      f"photo, {fig[f'{what}_seconds']:.1f} s")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
