"""Peak memory of texture extraction from one very large photo (a one-off measurement).

``python3 -m vebuild.bench.big_photo [SIDE]`` writes a SIDE × SIDE PNG (default 10900: 119 MP, just
under the 120 MP a project's photo may have; a 13000² photo, 169 MP, is refused before it is
decoded), a smooth gradient that compresses to well under a megabyte, as a scan or a stitched panorama
might), and extracts the example room's textures from it alone, in a fresh process so that the
peak is this run's. It prints the peak resident memory (Linux VmHWM) and its ratio to the photo's
decoded size (3 bytes a pixel: the least any extraction must hold once), per stage of the run.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image


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


def child(photo: str, side: int) -> dict[str, float]:
    """Run in the fresh process: one extraction from the photo; its figures."""
    from vebuild.project import sha256_file
    from vebuild.texture.extract import PhotoSource, extract
    from vebuild.texture.options import Options

    from ..actions import example_truth as truth

    model, cams = truth.true_model(), truth.true_cameras()
    cam = cams[0].resized(side, side)
    src = PhotoSource(cam.id, Path(photo), sha256_file(Path(photo)))
    base = _peak_mb()
    t = time.perf_counter()
    extract(model, [cam], {cam.id: src}, Options(texels_per_metre=200.0))
    return {"baseline_mb": base, "peak_mb": _peak_mb(), "seconds": time.perf_counter() - t}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--child"]:
        print(json.dumps(child(argv[1], int(argv[2]))))
        return 0
    side = int(argv[0]) if argv else 10900
    with tempfile.TemporaryDirectory(prefix="vebuild-big-photo-") as tmp:
        photo = Path(tmp) / "big.png"
        write_photo(photo, side)
        out = subprocess.run([sys.executable, "-m", "vebuild.bench.big_photo", "--child", str(photo), str(side)],
                             check=True, capture_output=True, text=True).stdout
        fig = json.loads(out.strip().splitlines()[-1])
        png_mb = photo.stat().st_size / 2**20
    decoded = 3 * side * side / 2**20
    print(f"photo {side}×{side} ({side * side / 1e6:.0f} MP), PNG {png_mb:.2f} MB, decoded {decoded:.0f} MB")
    print(f"peak resident memory {fig['peak_mb']:.0f} MB (before the extraction {fig['baseline_mb']:.0f} MB); "
          f"{fig['peak_mb'] / decoded:.2f}× the decoded photo; {fig['seconds']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
