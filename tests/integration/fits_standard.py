#!/usr/bin/python3
"""fits_standard.py - check FITS files against the standard header of
recon/io/cube.h, with tools that are not ours: fitsverify (HEASARC) and
astropy (checksums, WCS).  Run by tests/integration/test_fits_standard.c.

    fits_standard.py --version V [--wcs offset|none] [--bunit U]
                     [--binary SEP_ARCSEC PA_DEG SEP_TOL PA_TOL [--truth]]
                     FILE...

Every HDU of every FILE: fitsverify finds no error and no warning; astropy
opens it with checksum=True without a warning and CHECKSUM and DATASUM
verify.  The primary HDU: DATE (ISO-8601), CREATOR 'specklab* V', BUNIT
(U when given), HISTORY, and the WCS asked for.  --binary: the two
brightest stars of the image (the TRUTH extension with --truth, located
with the primary HDU's WCS) are SEP apart at position angle PA (north
through east) in the WCS's arcsec, within the tolerances.  One line per
file, "ok FILE" or "FAIL FILE: why"; exit status 1 when any failed.
"""
import argparse
import math
import re
import subprocess
import sys
import warnings

import numpy as np
from astropy.io import fits
from astropy.wcs import WCS


def fitsverify(path):
    out = subprocess.run(["fitsverify", path], capture_output=True, text=True).stdout
    m = re.search(r"Verification found (\d+) warning\(s\) and (\d+) error\(s\)", out)
    if not m:
        return "fitsverify gave no verdict: " + out[-300:]
    if m.group(1) != "0" or m.group(2) != "0":
        lines = [l for l in out.splitlines() if "***" in l or "Warning" in l or "Error" in l]
        return "fitsverify: " + " | ".join(lines[:6])
    return None


def checksums(hdul):
    for i, hdu in enumerate(hdul):
        if "CHECKSUM" not in hdu.header or "DATASUM" not in hdu.header:
            return "HDU %d has no CHECKSUM/DATASUM" % i
        if hdu.verify_datasum() != 1 or hdu.verify_checksum() != 1:
            return "HDU %d: DATASUM %d, CHECKSUM %d (1 = verified)" % (
                i, hdu.verify_datasum(), hdu.verify_checksum())
    return None


def keywords(h, version, bunit):
    if not re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\.\d+)?", str(h.get("DATE", ""))):
        return "DATE %r is not ISO-8601" % h.get("DATE")
    creator = str(h.get("CREATOR", ""))
    if not (creator.startswith("specklab") and creator.endswith(" " + version)):
        return "CREATOR %r, want 'specklab* %s'" % (creator, version)
    if not h.get("BUNIT"):
        return "no BUNIT"
    if bunit is not None and h["BUNIT"] != bunit:
        return "BUNIT %r, want %r" % (h["BUNIT"], bunit)
    if len(h.get("HISTORY", [])) == 0:
        return "no HISTORY"
    return None


def offset_wcs(h):
    if h.get("CTYPE1") != "EOFFSET" or h.get("CTYPE2") != "NOFFSET":
        return "CTYPE %r %r, want EOFFSET NOFFSET" % (h.get("CTYPE1"), h.get("CTYPE2"))
    if h.get("CUNIT1") != "arcsec" or h.get("CUNIT2") != "arcsec":
        return "CUNIT %r %r" % (h.get("CUNIT1"), h.get("CUNIT2"))
    if not (h["CDELT1"] < 0 < h["CDELT2"]):
        return "CDELT %g %g: east must be -x, north +y" % (h["CDELT1"], h["CDELT2"])
    want = (h["NAXIS1"] // 2 + 1, h["NAXIS2"] // 2 + 1)
    if (h["CRPIX1"], h["CRPIX2"]) != want:
        return "CRPIX %g %g, want %d %d" % (h["CRPIX1"], h["CRPIX2"], *want)
    return None


def peak(img, exclude=None, radius=3):
    """Brightest pixel (outside radius of exclude), refined by a 3x3
    centroid; returns (x, y), 0-based, x along NAXIS1."""
    a = np.nan_to_num(img.astype(float), nan=-np.inf)
    if exclude is not None:
        yy, xx = np.indices(a.shape)
        a[(xx - exclude[0]) ** 2 + (yy - exclude[1]) ** 2 <= radius ** 2] = -np.inf
    y, x = np.unravel_index(np.argmax(a), a.shape)
    win = np.clip(img[y - 1:y + 2, x - 1:x + 2].astype(float), 0, None)
    yy, xx = np.mgrid[y - 1:y + 2, x - 1:x + 2]
    return (float((win * xx).sum() / win.sum()), float((win * yy).sum() / win.sum()))


def binary(hdul, sep_want, pa_want, sep_tol, pa_tol, truth):
    h = hdul[0].header
    img = hdul["TRUTH"].data if truth else hdul[0].data
    if img.ndim != 2:
        return "image of %d axes" % img.ndim
    w = WCS(h, naxis=2)
    a = peak(img)
    b = peak(img, exclude=a)
    (ea, eb), (na, nb) = w.wcs_pix2world([a[0], b[0]], [a[1], b[1]], 0)
    east, north = eb - ea, nb - na
    sep = math.hypot(east, north)
    pa = math.degrees(math.atan2(east, north)) % 360.0
    dpa = (pa - pa_want + 180.0) % 360.0 - 180.0
    if abs(sep - sep_want) > sep_tol or abs(dpa) > pa_tol:
        return ("companion at %.4f arcsec, PA %.2f deg (pixels %.2f,%.2f -> %.2f,%.2f); "
                "want %.4f, %.2f" % (sep, pa, *a, *b, sep_want, pa_want))
    print("  %s: companion %.4f arcsec east %.4f north %.4f, PA %.2f deg" % (
        "TRUTH" if truth else "image", sep, east, north, pa))
    return None


def check(path, args):
    why = fitsverify(path)
    if why:
        return why
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with fits.open(path, checksum=True) as hdul:
            hdul.verify("exception")
            why = checksums(hdul) or keywords(hdul[0].header, args.version, args.bunit)
            h = hdul[0].header
            if not why and args.wcs == "offset":
                why = offset_wcs(h)
            if not why and args.wcs == "none" and any(k in h for k in ("CTYPE1", "CDELT1")):
                why = "a WCS without a plate scale"
            if not why and args.binary:
                why = binary(hdul, *args.binary, args.truth)
    bad = [str(c.message) for c in caught if "checksum" in str(c.message).lower()
           or "datasum" in str(c.message).lower()]
    return why or ("astropy: " + "; ".join(bad) if bad else None)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--version", required=True)
    p.add_argument("--wcs", choices=["offset", "none"])
    p.add_argument("--bunit")
    p.add_argument("--binary", nargs=4, type=float)
    p.add_argument("--truth", action="store_true")
    p.add_argument("files", nargs="+")
    args = p.parse_args()
    failed = 0
    for f in args.files:
        try:
            why = check(f, args)
        except Exception as e:  # a file astropy cannot take is a failure
            why = "%s: %s" % (type(e).__name__, e)
        print(("FAIL %s: %s" % (f, why)) if why else ("ok %s" % f))
        failed += why is not None
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
