#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""src/render/picture_metrics against scikit-image, through tests/unit/picture_metrics_probe
(argv[1]): for seeded picture pairs of several sizes, the probe's SSIM must equal
structural_similarity(a, b, channel_axis=-1, data_range=255) within 1e-6, its PSNR
peak_signal_noise_ratio(a, b, data_range=255) (capped at 100 dB as ours is) within 1e-6 dB, and
its perceptible share the percent of pixels with deltaE_ciede2000(rgb2lab(a), rgb2lab(b)) > 2
within 0.01 percentage points. A truncated PPM must be refused with its name and byte offset.
Exits 77 (CTest's skip) when numpy or scikit-image is missing."""
import os
import subprocess
import sys
import tempfile

try:
    import numpy as np
    from skimage.color import deltaE_ciede2000, rgb2lab
    from skimage.metrics import peak_signal_noise_ratio, structural_similarity
except ImportError as e:
    print(f"skipped: {e} (install python3-skimage)")
    sys.exit(77)

probe = sys.argv[1]
rng = np.random.default_rng(20240611)


def scene(h, w):
    """A picture-like image: smooth gradients with a few flat rectangles and mild noise."""
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([x * 255.0 / max(w - 1, 1), y * 255.0 / max(h - 1, 1),
                    127.5 + 100 * np.sin((x + 2 * y) / 9.0)], axis=-1)
    for _ in range(6):
        y0, x0 = rng.integers(0, h), rng.integers(0, w)
        img[y0:y0 + rng.integers(2, h // 3 + 3), x0:x0 + rng.integers(2, w // 3 + 3)] = rng.integers(0, 256, 3)
    img += rng.normal(0, 3, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def edited(a, share):
    """`a` with about `share` of its pixels changed: some by a few levels (near the CIEDE2000
    threshold, where rounding would show), some replaced outright."""
    b = a.astype(int)
    h, w, _ = a.shape
    chosen = rng.random((h, w)) < share
    small = chosen & (rng.random((h, w)) < 0.6)
    b[small] += rng.integers(-6, 7, (int(small.sum()), 3))
    big = chosen & ~small
    b[big] = rng.integers(0, 256, (int(big.sum()), 3))
    return np.clip(b, 0, 255).astype(np.uint8)


def write_ppm(path, img):
    h, w, _ = img.shape
    with open(path, "wb") as f:
        f.write(b"P6\n# picture_metrics check\n%d %d\n255\n" % (w, h))
        f.write(np.ascontiguousarray(img).tobytes())


def probe_numbers(dir_, a, b):
    pa, pb = os.path.join(dir_, "a.ppm"), os.path.join(dir_, "b.ppm")
    write_ppm(pa, a)
    write_ppm(pb, b)
    r = subprocess.run([probe, pa, pb], capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        raise RuntimeError(f"probe exit {r.returncode}: {r.stderr.strip()}")
    return [float(v) for v in r.stdout.split()]


cases = []
for h, w in [(512, 512), (29, 37), (7, 7), (12, 16), (64, 48)]:
    a = scene(h, w)
    cases += [(f"{w}x{h} 5% edited", a, edited(a, 0.05)), (f"{w}x{h} 40% edited", a, edited(a, 0.4)),
              (f"{w}x{h} unrelated", a, scene(h, w)), (f"{w}x{h} identical", a, a.copy())]
cases.append(("29x37 noise", rng.integers(0, 256, (37, 29, 3), dtype=np.uint8),
              rng.integers(0, 256, (37, 29, 3), dtype=np.uint8)))

failures = []
with tempfile.TemporaryDirectory() as tmp:
    for name, a, b in cases:
        got_ssim, got_psnr, got_share = probe_numbers(tmp, a, b)
        want_ssim = structural_similarity(a, b, channel_axis=-1, data_range=255)
        want_psnr = min(100.0, peak_signal_noise_ratio(a, b, data_range=255)) if not np.array_equal(a, b) else 100.0
        want_share = 100.0 * np.count_nonzero(deltaE_ciede2000(rgb2lab(a), rgb2lab(b)) > 2) / (a.shape[0] * a.shape[1])
        print(f"{name}: ssim {got_ssim:.9f} vs {want_ssim:.9f}, psnr {got_psnr:.6f} vs {want_psnr:.6f}, "
              f"perceptible {got_share:.4f}% vs {want_share:.4f}%")
        if abs(got_ssim - want_ssim) > 1e-6:
            failures.append(f"{name}: ssim {got_ssim!r}, scikit-image {want_ssim!r}")
        if abs(got_psnr - want_psnr) > 1e-6:
            failures.append(f"{name}: psnr {got_psnr!r}, scikit-image {want_psnr!r}")
        if abs(got_share - want_share) > 0.01:
            failures.append(f"{name}: perceptible {got_share!r}%, scikit-image {want_share!r}%")

    # A PPM cut inside its pixels: refused, naming the file and where its data ends.
    cut = os.path.join(tmp, "cut.ppm")
    write_ppm(cut, cases[0][1])
    with open(cut, "r+b") as f:
        f.truncate(os.path.getsize(cut) - 1)
    r = subprocess.run([probe, cut, cut], capture_output=True, text=True, timeout=120)
    if r.returncode != 1 or "cut.ppm: byte" not in r.stderr:
        failures.append(f"truncated PPM: exit {r.returncode}, stderr {r.stderr.strip()!r}")

for f in failures:
    print("FAIL", f)
sys.exit(1 if failures else 0)
