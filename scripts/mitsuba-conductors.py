#!/usr/bin/env python3
"""The table of named conductors in common/scene/spectra_data.cpp, computed from spectra.

Usage: mitsuba-conductors.py DIR [--write common/scene/spectra_data.cpp] [--check]

DIR holds Mitsuba's measured spectra, <name>.eta.spd and <name>.k.spd for every conductor name
(the files of Mitsuba's data/ior folder: lines "wavelength_nm value", '#' comments). Each spectrum
becomes linear sRGB by the rule written in common/scene/spectra.h with the tabulated_ior role
(unbounded, not weighted by D65), the way Mitsuba 3's RGB variants load `material="Au"`.
The CIE and D65 tables are read from common/scene/spectra_data.cpp, so the script and the C++
code share one copy of them.

Without --write the rows are printed. --check also compares, for every conductor, the reflectance
at normal incidence computed per channel from the RGB eta and k with the one computed from the
spectra (the spectral Fresnel reflectance converted as a reflectance, D65-weighted), and prints the
largest difference.
"""
import argparse
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
DATA = ROOT / "common" / "scene" / "spectra_data.cpp"

NAMES = ["a-C", "Ag", "Al", "AlAs", "AlSb", "Au", "Be", "Cr", "CsI", "Cu", "Cu2O", "CuO", "d-C",
         "Hg", "HgTe", "Ir", "K", "Li", "MgO", "Mo", "Na_palik", "Nb", "Ni_palik", "Rh", "Se",
         "SiC", "SnTe", "Ta", "Te", "ThF4", "TiC", "TiN", "TiO2", "VC", "V_palik", "VN", "W"]

CIE_MIN, CIE_MAX, CIE_SAMPLES, STEPS = 360.0, 830.0, 95, 1000
Y_NORMALIZATION = 1.0 / 106.7502593994140625
D65_NORMALIZATION = 1.0 / 98.99741751876255
XYZ_TO_SRGB = [[3.240479, -1.537150, -0.498535],
               [-0.969256, 1.875991, 0.041556],
               [0.055648, -0.204043, 1.057311]]


def read_tables(text):
    tables = {}
    for name in ("kCie1931X", "kCie1931Y", "kCie1931Z", "kD65"):
        m = re.search(name + r"\s*=\s*\{([^}]*)\}", text)
        if not m:
            sys.exit(f"{DATA}: table {name} not found")
        values = [float(v) for v in m.group(1).replace(",", " ").split()]
        if len(values) != CIE_SAMPLES:
            sys.exit(f"{DATA}: table {name} has {len(values)} values, expected {CIE_SAMPLES}")
        tables[name] = values
    return tables


def read_spd(path):
    wavelengths, values = [], []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        fields = line.split()
        if len(fields) != 2:
            sys.exit(f"{path}:{number}: expected 'wavelength value', got {line!r}")
        wavelengths.append(float(fields[0]))
        values.append(float(fields[1]))
    # Mitsuba reads a file as it is; one of its files (Se) repeats a wavelength below 360 nm,
    # where no sample falls, so repeats are allowed but decreasing wavelengths are not.
    if len(wavelengths) < 2 or any(b < a for a, b in zip(wavelengths, wavelengths[1:])):
        sys.exit(f"{path}: needs at least two increasing wavelengths")
    return wavelengths, values


def lerp_table(table, nm):
    t = (nm - CIE_MIN) * ((CIE_SAMPLES - 1) / (CIE_MAX - CIE_MIN))
    i0 = min(max(int(t), 0), CIE_SAMPLES - 2)
    w1 = t - i0
    return (1.0 - w1) * table[i0] + w1 * table[i0 + 1]


def to_rgb(tables, wavelengths, values, bounded, d65):
    xyz = [0.0, 0.0, 0.0]
    for i in range(STEPS):
        w = CIE_MIN + (i / (STEPS - 1)) * (CIE_MAX - CIE_MIN)
        if w < wavelengths[0] or w > wavelengths[-1]:
            continue
        j = 0
        while j + 2 < len(wavelengths) and wavelengths[j + 1] <= w:
            j += 1
        w0, w1 = wavelengths[j], wavelengths[j + 1]
        v = ((w - w1) * values[j] + (w0 - w) * values[j + 1]) / (w0 - w1)
        weight = v * Y_NORMALIZATION
        if d65:
            weight *= lerp_table(tables["kD65"], w) * D65_NORMALIZATION
        for c, name in enumerate(("kCie1931X", "kCie1931Y", "kCie1931Z")):
            xyz[c] += lerp_table(tables[name], w) * weight
    xyz = [c * (CIE_MAX - CIE_MIN) / STEPS for c in xyz]
    rgb = [sum(m * c for m, c in zip(row, xyz)) for row in XYZ_TO_SRGB]
    return [min(max(c, 0.0), 1.0) if bounded else max(c, 0.0) for c in rgb]


def cpp_float(value):
    text = f"{value:.6g}"
    if "." not in text and "e" not in text:
        text += ".0"
    return text + "f"


def fresnel_normal(eta, k):
    return ((eta - 1) ** 2 + k * k) / ((eta + 1) ** 2 + k * k)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("dir", type=pathlib.Path)
    parser.add_argument("--write", type=pathlib.Path)
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    tables = read_tables(DATA.read_text())

    rows, worst = [], (0.0, "")
    for name in NAMES:
        eta_w, eta_v = read_spd(args.dir / f"{name}.eta.spd")
        k_w, k_v = read_spd(args.dir / f"{name}.k.spd")
        eta = to_rgb(tables, eta_w, eta_v, False, False)
        k = to_rgb(tables, k_w, k_v, False, False)
        fmt = lambda v: ", ".join(cpp_float(c) for c in v)
        rows.append(f'    {{"{name}", {{{fmt(eta)}}}, {{{fmt(k)}}}}},')
        if args.check:
            # The spectral reflectance needs eta and k on one grid: the eta file's, with k
            # interpolated linearly (both files of a material share their grid in Mitsuba's data).
            def at(ws, vs, w):
                if w <= ws[0]:
                    return vs[0]
                for a in range(len(ws) - 1):
                    if ws[a] <= w <= ws[a + 1]:
                        f = (w - ws[a]) / (ws[a + 1] - ws[a])
                        return (1 - f) * vs[a] + f * vs[a + 1]
                return vs[-1]
            r_spec = [fresnel_normal(n, at(k_w, k_v, w)) for w, n in zip(eta_w, eta_v)]
            from_spectrum = to_rgb(tables, eta_w, r_spec, True, True)
            from_rgb = [fresnel_normal(n, kk) for n, kk in zip(eta, k)]
            diff = max(abs(a - b) for a, b in zip(from_spectrum, from_rgb))
            worst = max(worst, (diff, name))
            print(f"{name:9s} R(rgb eta,k) = {', '.join(f'{c:.4f}' for c in from_rgb)}   "
                  f"R(spectra) = {', '.join(f'{c:.4f}' for c in from_spectrum)}   "
                  f"max |diff| = {diff:.4f}", file=sys.stderr)
    if args.check:
        print(f"largest difference: {worst[0]:.4f} ({worst[1]})", file=sys.stderr)

    block = "\nconstexpr NamedConductor kNamedConductors[] = {\n" + "\n".join(rows) + "\n};\n"
    if args.write:
        text = args.write.read_text()
        new, count = re.subn(r"(// BEGIN CONDUCTORS\n).*?(// END CONDUCTORS)",
                             lambda m: m.group(1) + block.lstrip("\n") + m.group(2), text,
                             flags=re.S)
        if count != 1:
            sys.exit(f"{args.write}: no BEGIN/END CONDUCTORS block")
        args.write.write_text(new)
    else:
        print(block)


if __name__ == "__main__":
    main()
