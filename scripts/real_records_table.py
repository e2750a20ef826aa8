"""The table of data/README.md ("fracid on these records"): every real record of
python/tests/test_real_records.py fitted by `fracid time FILE --json --plain` and with the
defaults, against that file's integer baseline on fracid's split (scipy), one markdown row each.

    python/ci.sh --venv-only /tmp/venv          # numpy, scipy, pytest
    /tmp/venv/bin/python scripts/real_records_table.py target/release/fracid

Nothing is written beside the records (each report goes to standard output)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "python" / "tests"))
import test_real_records as T  # noqa: E402


def figure(out: dict, code: int) -> str:
    v = out["fit"]["validation"]
    text = f"{v['rmse']:.4g} ({v['nrmse_percent']:.2f})"
    return f"exit {code}: {text}" if code else text


def main() -> None:
    binary = sys.argv[1]
    for name, (rel, _) in T.RECORDS.items():
        path = T.DATA / rel
        plain = T.run_fracid(binary, path, "--plain")
        default = T.run_fracid(binary, path)
        n_est, first, _, rmse, kind = T.held_out(default[0])
        best, _ = T.baseline_on_split(name, n_est, first)
        model = default[0]["model_is"].split("(", 1)[-1].rsplit(")", 1)[0]
        delay = best["delay_samples"]
        base = f"{best['val_rmse']:.4g} ({best['val_nrmse']:.2f}), order {best['order']}"
        base += f" + {delay} samples" if delay else ""
        at = f"tail from {first}" if kind == "response_tail" else str(first)
        ok = default[1] == 0 and rmse <= best["val_rmse"] * (1.0 + T.TOL_RMSE)
        print(f"| {name} | {at} | {figure(*plain)} | {figure(*default)}, {model} | {base} |"
              + ("" if ok else " BELOW THE BASELINE |"))


if __name__ == "__main__":
    main()
