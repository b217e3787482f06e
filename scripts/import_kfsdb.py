#!/usr/bin/env python3
"""Converts the KFSDB tests of github.com/gagankaushikmanyam/mechanics-sand-model into
data/lab/kfsdb/*.csv (SI units, named columns) and data/lab/kfsdb/tests.csv (one row per test).

  python3 scripts/import_kfsdb.py GIT_DIR COMMIT [OUT_DIR]

GIT_DIR is a clone (bare or not) of that repository; files are read with `git show COMMIT:path`.
Quirks handled (data/lab/SOURCES.md): CRLF, tab- or space-separated columns, TMD void ratio headed
"[%]" (a ratio), TMD10's German one-line header ("** ... Porenzahl ..."), different column orders
of TMU-all and TMU-MT-AP-all. Values are converted, never altered; TMU-all files (up to 40,000
rows) are thinned by the rule in thin().
"""
import csv
import os
import subprocess
import sys

REPO = "gagankaushikmanyam/mechanics-sand-model"

# Source column (first header word, lower case) -> (our name, factor to SI).
PCT, KPA = 0.01, 1e3
TMD_COLS = [("eps1", "eps_a", PCT), ("epsv", "eps_v", PCT), ("eps3", "eps_r", PCT), ("epsq", "eps_q", PCT),
            ("void", "e", 1.0), ("q", "q", KPA), ("p", "p", KPA), ("eta", "eta", 1.0)]
TMU_NAMES = {"eps1": ("eps_a", PCT), "u": ("u", KPA), "sigma3": ("sigma_r", KPA), "sigma3'": ("sigma_r_eff", KPA),
             "sigma1": ("sigma_a", KPA), "sigma1'": ("sigma_a_eff", KPA), "p": ("p", KPA), "q": ("q", KPA)}
TMU_ORDER = ["eps_a", "u", "sigma_r", "sigma_r_eff", "sigma_a", "sigma_a_eff", "p", "q"]
OE_COLS = [("sigma1", "sigma_a", KPA), ("eps1", "eps_a", PCT), ("void", "e", 1.0)]


def git_show(git_dir, commit, path):
    out = subprocess.run(["git", "--git-dir", git_dir, "show", "%s:%s" % (commit, path)], check=True,
                         capture_output=True)
    return out.stdout.decode("latin-1").replace("\r", "")


def numeric_rows(text):
    rows = []
    for line in text.split("\n"):
        f = line.split()
        if not f:
            continue
        try:
            rows.append([float(x) for x in f])
        except ValueError:
            continue  # header or unit line
    return rows


def header_words(text):
    first = text.split("\n")[0].replace("**", " ")
    # "Void ratio" / "eta = q/p": keep the first word of multi-word names.
    return first.replace("Void ratio", "void").replace("Porenzahl", "void").replace("eta = q/p", "eta").split()


def thin(rows, ia, ip, iq):
    """Keeps the first and last row, the rows of least p' and largest |q|, and a row whenever,
    since the last kept row, |d eps_a| >= 5e-4 or |d p'| or |d q| >= 0.5 % of max |q|."""
    qmax = max(abs(r[iq]) for r in rows)
    must = {0, len(rows) - 1, min(range(len(rows)), key=lambda i: rows[i][ip]),
            max(range(len(rows)), key=lambda i: abs(rows[i][iq]))}
    kept, last = [], None
    for i, r in enumerate(rows):
        if i in must or last is None or abs(r[ia] - last[ia]) >= 5e-4 or abs(r[ip] - last[ip]) >= 5e-3 * qmax \
                or abs(r[iq] - last[iq]) >= 5e-3 * qmax:
            kept.append(r)
            last = r
    return kept


def write_csv(path, names, rows, comments):
    with open(path, "w", newline="") as f:
        for c in comments:
            f.write("# " + c + "\n")
        w = csv.writer(f, lineterminator="\n")
        w.writerow(names)
        for r in rows:
            w.writerow(["%.10g" % v for v in r])


def main():
    git_dir, commit = sys.argv[1], sys.argv[2]
    out = sys.argv[3] if len(sys.argv) > 3 else os.path.join(os.path.dirname(__file__), "..", "data", "lab", "kfsdb")
    os.makedirs(out, exist_ok=True)
    files = subprocess.run(["git", "--git-dir", git_dir, "ls-tree", "-r", "--name-only", commit], check=True,
                           capture_output=True, text=True).stdout.split()
    index = []
    src = lambda path: "%s, %s, commit %s" % (REPO, path, commit)
    units = "SI: stresses in Pa (effective unless named otherwise), strains as fractions; compression positive"

    def key(p):
        base = os.path.basename(p)[:-4]
        return (base.rstrip("0123456789"), int(base[len(base.rstrip("0123456789")):]))

    for path in sorted((f for f in files if f.endswith(".dat")), key=key):
        name = os.path.basename(path)[:-4]
        text = git_show(git_dir, commit, path)
        rows = numeric_rows(text)
        words = header_words(text)
        n_src = len(rows)
        if path.startswith("OE-all/"):
            assert words[:3] == ["sigma1", "eps1", "void"], (path, words)
            names = [c[1] for c in OE_COLS]
            rows = [[r[i] * c[2] for i, c in enumerate(OE_COLS)] for r in rows]
            kind, direction, drainage = "oedometer", "compression", "drained"
            e0, e0_src = rows[0][2], "file: first row, sigma_a = 0"
            sa0 = sr0 = float("nan")
            note = "load to 407 kPa, unload to 0, reload to 407 kPa"
        elif path.startswith("TMD-all/"):
            assert [w.lower() for w in words[:8]] == [c[0] for c in TMD_COLS], (path, words)
            names = [c[1] for c in TMD_COLS]
            rows = [[r[i] * c[2] for i, c in enumerate(TMD_COLS)] for r in rows]
            kind, direction, drainage = "triaxial", "compression", "drained"
            e0, e0_src = rows[0][4], "file: first row"
            p0, q0 = rows[0][6], rows[0][5]
            sa0, sr0 = p0 + 2.0 * q0 / 3.0, p0 - q0 / 3.0
            note = ""
        else:
            cols = [TMU_NAMES[w] for w in words[:8]]
            perm = [TMU_ORDER.index(c[0]) for c in cols]
            conv = []
            for r in rows:
                v = [0.0] * 8
                for j, c in enumerate(cols):
                    v[perm[j]] = r[j] * c[1]
                conv.append(v)
            rows = conv
            names = TMU_ORDER
            kind, drainage = "triaxial", "undrained"
            ext = min(r[0] for r in rows) < -1e-3
            direction = "extension" if ext else "compression"
            e0, e0_src = float("nan"), "not in the file; no published table found"
            sa0, sr0 = rows[0][5], rows[0][3]
            note = ""
            if path.startswith("TMU-all/"):
                rows = thin(rows, 0, 6, 7)
                note = "thinned from %d rows (scripts/import_kfsdb.py thin())" % n_src
        if kind == "oedometer":
            p0_txt = ""
        else:
            p0_txt = "%.6g" % ((sa0 + 2 * sr0) / 3.0)
        comments = ["KFSDB test %s (Karlsruhe fine sand; Wichtmann & Triantafyllidis 2016, Acta Geotech. 11)" % name,
                    "measured; source: %s; see data/lab/SOURCES.md" % src(path),
                    "%s %s%s; %s" % (drainage, kind, " " + direction if kind == "triaxial" else "",
                                     "e0 unknown (%s)" % e0_src if e0 != e0 else "e0 = %.6g (%s)" % (e0, e0_src)),
                    units]
        if note:
            comments.append(note)
        write_csv(os.path.join(out, name + ".csv"), names, rows, comments)
        index.append({"test": name, "file": "kfsdb/%s.csv" % name, "type": kind, "drainage": drainage,
                      "direction": direction if kind == "triaxial" else "", "e0": "" if e0 != e0 else "%.6g" % e0,
                      "e0_source": e0_src, "sigma_a0_eff_Pa": "" if sa0 != sa0 else "%.6g" % sa0,
                      "sigma_r0_eff_Pa": "" if sr0 != sr0 else "%.6g" % sr0, "p0_eff_Pa": p0_txt,
                      "rows_source": n_src, "rows": len(rows), "source_path": path})
    with open(os.path.join(out, "tests.csv"), "w", newline="") as f:
        f.write("# KFSDB tests in data/lab/kfsdb (one row per file); %s; see data/lab/SOURCES.md\n" % src("*"))
        w = csv.DictWriter(f, fieldnames=list(index[0].keys()), lineterminator="\n")
        w.writeheader()
        w.writerows(index)
    print("wrote %d tests to %s" % (len(index), out))


if __name__ == "__main__":
    main()
