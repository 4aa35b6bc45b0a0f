#!/usr/bin/env python3
"""The test binaries a `cargo test --no-run --message-format=json` built, from its output on
stdin: one path a line, or `NAME PATH` with --named; only the targets named as arguments where
any are given (tools/gpu-run.sh packs them, tools/four-lanes.sh runs them).

    cargo test --no-run --message-format=json 2> /dev/null | python3 tools/test_binaries.py
    ... | python3 tools/test_binaries.py --named izb pvssm
"""
import json
import sys

args = sys.argv[1:]
named = "--named" in args
want = {a for a in args if a != "--named"}
for line in sys.stdin:
    m = json.loads(line)
    target = m.get("target", {})
    if (m.get("reason") == "compiler-artifact" and m.get("executable")
            and target.get("kind") == ["test"] and (not want or target.get("name") in want)):
        print(f"{target['name']} {m['executable']}" if named else m["executable"])
