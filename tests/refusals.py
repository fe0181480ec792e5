"""The one check of a refusal as a user sees it, shared by the CLI tests."""

from __future__ import annotations

import json

from seqdesign.cli import main


def refused(runner, tmp_path, args, *parts):
    """Run ``args`` in tmp_path; expect a one-line 'error: ...' naming parts, nothing written."""
    before = sorted(p.name for p in tmp_path.iterdir())
    res = runner.invoke(main, args)
    assert res.exit_code != 0
    assert isinstance(res.exception, SystemExit), repr(res.exception)  # handled, not a crash
    assert "Traceback" not in res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("error: ")
    for part in parts:
        assert part in lines[0], f"{part!r} not in {lines[0]!r}"
    if "--json" in args:  # issue 17: with --json a refusal is also one JSON document
        assert json.loads(res.stdout)["error"]["what"] in lines[0]
    else:
        assert res.stdout == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    return lines[0]
