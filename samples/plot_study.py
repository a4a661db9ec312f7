#!/usr/bin/python3
"""Charts of an `rvegen study` (its study.json): for each property named, the property against
the box size with the 95 % confidence intervals of the mean, and its variance against the volume
on log axes with the fitted law D^2(V) = K V^-alpha and the recommended volume marked.

usage: /usr/bin/python3 samples/plot_study.py STUDY_DIR [PROPERTY ...] [-o PNG]
  (default property: conductivity.mean when the study has it, else the first one; default
  output STUDY_DIR/study.png)
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(argv):
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        return 0 if argv else 2
    study_dir, rest = argv[0], argv[1:]
    out = os.path.join(study_dir, "study.png")
    if "-o" in rest:
        i = rest.index("-o")
        out = rest[i + 1]
        rest = rest[:i] + rest[i + 2:]
    with open(os.path.join(study_dir, "study.json")) as f:
        study = json.load(f)
    props = study["properties"]
    names = rest or (["conductivity.mean"] if "conductivity.mean" in props else [next(iter(props))])
    for n in names:
        if n not in props:
            raise SystemExit("no property %s in the study (it has: %s)" % (n, ", ".join(props)))
    fig, axes = plt.subplots(len(names), 2, figsize=(10, 3.8 * len(names)), squeeze=False)
    for row, name in enumerate(names):
        p = props[name]
        rows = p["per_size"]
        sizes = [r["size"] for r in rows]
        means = [r["mean"] for r in rows]
        lo = [r["mean"] - r["ci95"][0] for r in rows]
        hi = [r["ci95"][1] - r["mean"] for r in rows]
        ax = axes[row][0]
        ax.errorbar(sizes, means, yerr=[lo, hi], fmt="o-", capsize=4)
        ax.set_xlabel("box edge (multiple of the scene's box)")
        ax.set_ylabel(name)
        ax.set_title("%s: mean and 95 %% confidence interval (n = %d)"
                     % (name, study["realizations"]), fontsize=9)
        ax.grid(alpha=0.3)
        ax = axes[row][1]
        vols = [r["volume"] for r in rows if r["sd"] > 0]
        var = [r["sd"] ** 2 for r in rows if r["sd"] > 0]
        law = p["variance_law"]
        rec = p["recommended"]
        if vols:
            ax.loglog(vols, var, "o", label="measured D^2(V)")
        if "K" in law:
            v_lo = min(vols) / 2 if vols else 1e-3
            v_hi = max([max(vols) * 2] + ([rec["volume"] * 1.5] if rec.get("volume") else []))
            xs = [v_lo * (v_hi / v_lo) ** (k / 50.0) for k in range(51)]
            ax.loglog(xs, [law["K"] * x ** -law["alpha"] for x in xs], "-",
                      label="K V^-alpha, alpha = %.2f" % law["alpha"])
        if rec.get("volume"):
            ax.axvline(rec["volume"], color="C3", ls="--",
                       label="recommended V = %.3g (edge x%.2f)" % (rec["volume"], rec["size"]))
        if law.get("exact"):
            ax.text(0.5, 0.5, "does not vary between realizations", ha="center",
                    transform=ax.transAxes)
        ax.set_xlabel("volume V")
        ax.set_ylabel("variance between realizations")
        ax.set_title("variance law, target relative error %g" % study["target_error"], fontsize=9)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="best", framealpha=0.6)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print("wrote", out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
