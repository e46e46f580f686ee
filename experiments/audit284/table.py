"""Summarise results/{284,head}/*.xml into a markdown table: item, test, result at 284a76f, result at HEAD."""
import glob
import os
import re
import sys
import xml.etree.ElementTree as ET

RC = {}
for lf in sorted(glob.glob("/tmp/audit284/results_284_*.log"), key=lambda p: ("rerun" in p, p)):
    for line in open(lf):
        name, _, rc = line.strip().rpartition(" rc=")
        RC[name] = rc
HEAD = {}
for hx in sorted(glob.glob("/tmp/audit284/results/head_*.xml")):  # head_all first, later reruns override it
    one = {}
    for c in ET.parse(hx).getroot().iter("testcase"):
        one.setdefault(c.get("name").split("[")[0], []).append(c)
    HEAD.update(one)


def summary(where, func):
    if where == "head":
        cases = HEAD.get(func)
        if not cases:
            return "not run"
    else:
        x = f"/tmp/audit284/results/{where}/{func}.xml"
        if RC.get(func) == "124":
            return "fail: hangs, killed by the 600 s timeout"
        if not os.path.exists(x) or os.path.getsize(x) == 0:
            return "not run"
        cases = ET.parse(x).getroot().iter("testcase")
    res = []
    for c in cases:
        f = c.find("failure") if c.find("failure") is not None else c.find("error")
        s = c.find("skipped")
        if f is not None:
            msg = (f.get("message") or "").splitlines()[0][:90]
            kind = "ImportError" if "ImportError" in msg else ("AttributeError" if "AttributeError" in msg else
                   ("assert" if "ssert" in msg or "DID NOT" in msg or "Failed" in msg else msg.split(":")[0][:40]))
            res.append(("fail", kind, msg))
        elif s is not None:
            res.append(("skip", "", s.get("message", "")[:60]))
        else:
            res.append(("pass", "", ""))
    n = len(res)
    fails = [r for r in res if r[0] == "fail"]
    passes = sum(r[0] == "pass" for r in res)
    if not fails:
        return f"pass ({passes}/{n})" if n > 1 else "pass"
    kinds = sorted({r[1] for r in fails})
    return f"fail ({len(fails)}/{n}: {', '.join(kinds)})" if n > 1 else f"fail ({kinds[0]})"

funcs = []
for file in sys.argv[1:]:
    funcs += [(file, m) for m in re.findall(r"^def (test_[a-z0-9_]+)", open(f"/tmp/audit284/{file}").read(), re.M)]
print("| item | test | 284a76f | HEAD |")
print("|---|---|---|---|")
for _file, f in funcs:
    item = re.match(r"test_item([0-9_]+?)_[a-z]", f)
    item = item.group(1).replace("_", ", ") if item else ("fuzz" if "fuzz" in f else "17")
    print(f"| {item} | `{f}` | {summary('284', f)} | {summary('head', f)} |")
