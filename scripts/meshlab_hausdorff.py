#!/usr/bin/env python3
"""Checks `hdlod simplify`'s Hausdorff bound against MeshLab's.

For bunny and horse (the classic meshes: `--meshes DIR`, or the `meshes/`
of the test data at `$HDLOD_DATA`, e.g. HDLOD_DATA=../shared/data), simplified
to 10% and 2% of their triangles by each method, MeshLab measures the
Hausdorff distance in both directions with dense surface sampling
(pymeshlab's get_hausdorff_distance: vertices, edges and faces sampled,
exact closest points). Ours must be a bound, so at least MeshLab's maximum,
and a tight one: at most 1.3 times it. Prints a markdown table; exits 1 if a
row fails.

Creates its own virtualenv in .venv (gitignored) with pymeshlab from PyPI
on first use, and builds `hdlod` in release mode.
"""

import argparse
import json
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
OUT = ROOT / "out" / "meshlab"
MODELS = [("bunny", "stanford-bunny.obj"), ("horse", "horse.ply")]
RATIOS = [0.1, 0.02]
METHODS = ["qem", "clustering"]
SAMPLES_PER_TRIANGLE = 20
TIGHTNESS = 1.3


def venv_python() -> Path:
    return VENV / "bin" / "python"


def ensure_venv() -> None:
    """Re-runs this script inside .venv, creating it and installing pymeshlab."""
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not venv_python().exists():
        venv.create(VENV, with_pip=True)
    probe = subprocess.run([venv_python(), "-c", "import pymeshlab"], capture_output=True)
    if probe.returncode != 0:
        subprocess.run([venv_python(), "-m", "pip", "install", "--quiet", "pymeshlab"], check=True)
    os.execv(venv_python(), [str(venv_python()), __file__, *sys.argv[1:]])


def data_dir(meshes: str | None) -> Path:
    """`--meshes DIR`, else `$HDLOD_DATA/meshes`."""
    if meshes is not None:
        d = Path(meshes)
    elif "HDLOD_DATA" in os.environ:
        d = Path(os.environ["HDLOD_DATA"]) / "meshes"
    else:
        sys.exit(
            "no meshes: give --meshes DIR or set HDLOD_DATA to the directory whose meshes/ holds "
            "stanford-bunny.obj and horse.ply (github.com/alecjacobson/common-3d-test-models, folder data/)"
        )
    if not d.is_dir():
        sys.exit(f"{d}: no such directory of meshes")
    return d


def hdlod() -> Path:
    subprocess.run(["cargo", "build", "--release", "--quiet", "-p", "hdlod-server"], cwd=ROOT, check=True)
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return target / "release" / "hdlod"


def meshlab_distance(original: Path, simplified: Path) -> tuple[float, float]:
    """MeshLab's max distance original->simplified and simplified->original."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(original))
    ms.load_new_mesh(str(simplified))
    # A mesh is its triangles: vertices no face uses (the bunny has 1,113)
    # are not part of the surface, but MeshLab's vertex sampling would
    # measure them.
    for m in (0, 1):
        ms.set_current_mesh(m)
        ms.meshing_remove_unreferenced_vertices()
    # Points farther than maxdist are left out of MeshLab's statistics: allow
    # the whole diagonal so that none is.
    diagonal = ms.mesh(0).bounding_box().diagonal()
    absolute = getattr(pymeshlab, "PureValue", None) or getattr(pymeshlab, "AbsoluteValue")
    result = []
    for sampled, target in ((0, 1), (1, 0)):
        faces = ms.mesh(sampled).face_number()
        r = ms.get_hausdorff_distance(
            sampledmesh=sampled,
            targetmesh=target,
            samplevert=True,
            sampleedge=True,
            sampleface=True,
            samplenum=max(faces * SAMPLES_PER_TRIANGLE, 100_000),
            maxdist=absolute(diagonal),
        )
        result.append(r["max"])
    return result[0], result[1]


def main() -> int:
    parser = argparse.ArgumentParser(description="hdlod's Hausdorff bound against MeshLab's")
    parser.add_argument("--meshes", help="directory of stanford-bunny.obj and horse.ply (default: $HDLOD_DATA/meshes)")
    meshes = data_dir(parser.parse_args().meshes)
    ensure_venv()
    exe = hdlod()
    OUT.mkdir(parents=True, exist_ok=True)
    rows = []
    failed = 0
    for name, file in MODELS:
        original = meshes / file
        for ratio in RATIOS:
            for method in METHODS:
                simplified = OUT / f"{name}-{method}-{ratio}.obj"
                run = subprocess.run(
                    [exe, "simplify", original, simplified, "--method", method, "--ratio", str(ratio), "--json"],
                    capture_output=True,
                    text=True,
                    check=True,
                )
                ours = json.loads(run.stdout)
                ab, ba = meshlab_distance(original, simplified)
                theirs = max(ab, ba)
                bound = ours["hausdorff"]
                ok = theirs <= bound <= TIGHTNESS * theirs
                failed += not ok
                rows.append(
                    f"| {name} | {method} | {ratio:.0%} | {ours['triangles_in']} -> {ours['triangles_out']} "
                    f"| {ours['seconds'] * 1e3:.1f} | {ab:.6f} | {ba:.6f} | {bound:.6f} | {bound / theirs:.4f} "
                    f"| {ours['mean']:.6f} | {ours['volume_ratio']:.4f} | {ours['area_ratio']:.4f} "
                    f"| {'yes' if ok else 'NO'} |"
                )
    print("| model | method | kept | triangles | ms | MeshLab in->out | MeshLab out->in | our bound "
          "| bound / MeshLab max | our mean | volume ratio | area ratio | ok |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
