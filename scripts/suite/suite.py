"""Runner: plan the jobs, run one job (generate, diagnose from 3 and from 1
recording, score), summarize.

  suite.py plan [QUICK]                       -> lines "robot case seed"
  suite.py job BINARY OUTDIR robot case seed  -> OUTDIR/cases/<robot>-<case>-s<seed>/result.json
  suite.py summarize OUTDIR                   -> OUTDIR/results.json, OUTDIR/summary.txt
"""
import glob
import json
import os
import shutil
import subprocess
import sys
import time

from gen import CASES, generate
from score import score

SEEDS = {"panda": [1, 2, 3, 4, 5, 6], "kinova3": [1, 2, 3, 4, 5, 6], "ur10e": [1, 2, 3, 4, 5, 6]}
QUICK_SEEDS = {"panda": [1], "kinova3": [1], "ur10e": [1]}
QUICK_CASES = {"panda": CASES, "kinova3": CASES, "ur10e": CASES}


def plan(quick):
    jobs = []
    for robot in ("panda", "ur10e", "kinova3"):  # slow ones first, for the 2-job pool
        seeds = QUICK_SEEDS[robot] if quick else SEEDS[robot]
        cases = QUICK_CASES[robot] if quick else CASES
        for seed in seeds:
            for case in cases:
                jobs.append(f"{robot} {case} {seed}")
    return jobs


def run_diagnose(binary, toml, files, out_json, out_err):
    t0 = time.time()
    try:
        p = subprocess.run([binary, "diagnose", "--model", toml, "--data", *files, "--format", "json"],
                           capture_output=True, text=True, timeout=1800)
        code, stdout, stderr = p.returncode, p.stdout, p.stderr
    except subprocess.TimeoutExpired as e:
        code, stdout, stderr = "timeout", e.stdout or "", (e.stderr or "") + "\nTIMEOUT"
    wall = time.time() - t0
    with open(out_json, "w") as f:
        f.write(stdout if isinstance(stdout, str) else stdout.decode())
    with open(out_err, "w") as f:
        f.write(stderr if isinstance(stderr, str) else stderr.decode())
    try:
        report = json.loads(stdout) if stdout.strip() else None
    except json.JSONDecodeError:
        report = None
    panic = "panicked" in (stderr if isinstance(stderr, str) else "")
    return code, report, wall, panic


def job(binary, outdir, robot, case, seed):
    seed = int(seed)
    d = os.path.join(outdir, "cases", f"{robot}-{case}-s{seed}")
    if os.path.exists(d):
        shutil.rmtree(d)
    os.makedirs(d)
    t0 = time.time()
    truth = generate(robot, case, seed, d)
    tgen = time.time() - t0
    entries = []
    for nrec in (3, 1):
        files = truth["files"][:nrec]
        code, report, wall, panic = run_diagnose(binary, truth["toml"], files,
                                                 os.path.join(d, f"diagnose_{nrec}rec.json"),
                                                 os.path.join(d, f"diagnose_{nrec}rec.stderr"))
        r = score(truth, report, code)
        r.update(suite=robot, case=case, seed=seed, recordings=nrec, rate_hz=truth["rate_hz"],
                 qd=truth["noise"]["qd"], seconds=round(wall, 2), panic=panic,
                 effects_truth=truth["effects"])
        if panic:
            r["error"] = (r["error"] or "") + " PANIC"
        entries.append(r)
    if not os.environ.get("KEEP_DATA"):
        for f in truth["files"]:
            os.remove(f)
    with open(os.path.join(d, "result.json"), "w") as f:
        json.dump(dict(entries=entries, generate_seconds=round(tgen, 2)), f, indent=1)
    s = " ".join(f"{e['recordings']}rec:{'PASS' if e['strict_pass'] else 'FAIL'}({e['seconds']}s)" for e in entries)
    print(f"{robot:8s} {case:14s} s{seed} {s}", flush=True)


def summarize(outdir, wall=None):
    entries = []
    for p in sorted(glob.glob(os.path.join(outdir, "cases", "*", "result.json"))):
        with open(p) as f:
            entries += json.load(f)["entries"]
    order = {c: i for i, c in enumerate(CASES)}
    entries.sort(key=lambda e: (e["suite"], order.get(e["case"], 99), e["seed"], -e["recordings"]))
    with open(os.path.join(outdir, "results.json"), "w") as f:
        json.dump(entries, f, indent=1)
    L = []
    L.append(f"sdnn diagnose independent suite: {len(entries)} runs"
             + (f", wall {wall:.0f} s" if wall else ""))
    L.append("")
    L.append(f"{'suite':10s} {'recs':>4s} {'strict':>9s} {'lenient':>9s} {'errors':>6s} {'coverage':>16s}")
    tot = dict(n=0, s=0, l=0, err=0, cov=0, ncov=0)
    for suite in sorted({e["suite"] for e in entries}):
        for nrec in (3, 1):
            es = [e for e in entries if e["suite"] == suite and e["recordings"] == nrec]
            if not es:
                continue
            s = sum(e["strict_pass"] for e in es); l = sum(e["lenient_pass"] for e in es)
            err = sum(e["error"] is not None for e in es)
            cov = [c["covered"] for e in es for c in e["coverage"]]
            L.append(f"{suite:10s} {nrec:4d} {s:4d}/{len(es):<4d} {l:4d}/{len(es):<4d} {err:6d} "
                     + (f"{sum(cov):5d}/{len(cov):<5d}{100*sum(cov)/len(cov):5.1f}%" if cov else "    -"))
            tot["n"] += len(es); tot["s"] += s; tot["l"] += l; tot["err"] += err
            tot["cov"] += sum(cov); tot["ncov"] += len(cov)
    L.append(f"{'all':10s} {'':4s} {tot['s']:4d}/{tot['n']:<4d} {tot['l']:4d}/{tot['n']:<4d} {tot['err']:6d} "
             + (f"{tot['cov']:5d}/{tot['ncov']:<5d}{100*tot['cov']/max(tot['ncov'],1):5.1f}%"))
    secs = sorted(e["seconds"] for e in entries)
    codes = {}
    for e in entries:
        codes[str(e["exit_code"])] = codes.get(str(e["exit_code"]), 0) + 1
    L.append(f"exit codes: {codes}; panics: {sum(bool(e.get('panic')) for e in entries)}; diagnose time per run: "
             f"median {secs[len(secs)//2]:.1f} s, max {secs[-1]:.1f} s, sum {sum(secs):.0f} s")
    L.append("")
    L.append("strict: exactly the hidden effects named (kind and joint/link); lenient: also counts a")
    L.append("hidden effect as found when the kind named in its place lists it in `ambiguous_with`.")
    L.append("")
    # per case
    L.append("per case (strict passes, 3 recordings / 1 recording):")
    for suite in sorted({e["suite"] for e in entries}):
        parts = []
        for c in CASES:
            es = [e for e in entries if e["suite"] == suite and e["case"] == c]
            if not es:
                continue
            a = [e for e in es if e["recordings"] == 3]; b = [e for e in es if e["recordings"] == 1]
            parts.append(f"{c} {sum(e['strict_pass'] for e in a)}/{len(a)},{sum(e['strict_pass'] for e in b)}/{len(b)}")
        L.append(f"  {suite}: " + "; ".join(parts))
    L.append("")
    # coverage by parameter kind
    by = {}
    for e in entries:
        for c in e["coverage"]:
            k = c["kind"] + "." + c["param"].split("[")[0]
            by.setdefault(k, []).append(c["covered"])
    L.append("interval coverage by kind.parameter (covered/checked):")
    L.append("  " + "; ".join(f"{k} {sum(v)}/{len(v)}" for k, v in sorted(by.items())))
    L.append("")
    L.append("failures (hidden | named; missing, extra):")
    for e in entries:
        if e["strict_pass"]:
            continue
        head = f"- {e['suite']} {e['case']} s{e['seed']} {e['recordings']}rec @{e['rate_hz']:.0f}Hz"
        if e["error"]:
            L.append(f"{head}: ERROR {e['error']}" + (f" findings: {e.get('findings')}" if e.get("findings") else ""))
            continue
        L.append(f"{head}: hidden [{'; '.join(e['hidden']) or 'nothing'}]")
        L.append(f"    named [{'; '.join(e['named']) or 'nothing'}]")
        if e["missing"]:
            L.append(f"    missing: {'; '.join(e['missing'])}")
        if e["extra"]:
            amb = [f"{d['kind']}{'' if d['where'] is None else ' ' + str(d['where'])} ~ {', '.join(d['ambiguous_with'])}"
                   for d in e["named_detail"] if d["ambiguous_with"]]
            L.append(f"    extra: {'; '.join(e['extra'])}" + (f"  (ambiguous_with: {' / '.join(amb)})" if amb else ""))
    L.append("")
    misses = [(e, c) for e in entries for c in e["coverage"] if not c["covered"]]
    L.append(f"intervals that miss the truth ({len(misses)}):")
    for e, c in misses:
        L.append(f"  {e['suite']} {e['case']} s{e['seed']} {e['recordings']}rec {c['kind']}{fmt(c['where'])} {c['param']}: "
                 f"truth {c['truth']:.4g}, value {c['value'] if c['value'] is None else format(c['value'], '.4g')}, "
                 f"ci95 [{c['ci95'][0]:.4g}, {c['ci95'][1]:.4g}]")
    with open(os.path.join(outdir, "summary.txt"), "w") as f:
        f.write("\n".join(L) + "\n")
    print("\n".join(L))


def fmt(w):
    return "" if w is None else (f" j{w}" if isinstance(w, int) else f" {w}")


if __name__ == "__main__":
    cmd = sys.argv[1]
    if cmd == "plan":
        quick = len(sys.argv) > 2 and sys.argv[2] not in ("", "0")
        print("\n".join(plan(quick)))
    elif cmd == "job":
        try:
            job(*sys.argv[2:7])
        except Exception as exc:  # a harness failure must show, not vanish in xargs
            import traceback
            traceback.print_exc()
            print(f"HARNESS ERROR {' '.join(sys.argv[4:7])}: {exc}", flush=True)
    elif cmd == "summarize":
        summarize(sys.argv[2], float(sys.argv[3]) if len(sys.argv) > 3 else None)
    else:
        raise SystemExit(__doc__)
