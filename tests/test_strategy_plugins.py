"""Strategies as plug-ins (issue 18): the entry-point group ``urdfpost.strategies``, the live
strategy table, the command line's ``--strategy`` and ``compare`` with strategies from other
packages or registered by a script, and the example plug-in ``examples/strategy_plugin``.

The plug-in is "installed" the way pip installs it, without pip: a ``*.dist-info`` directory
with an ``entry_points.txt`` on ``sys.path`` (importlib.metadata finds it there).
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from urdfpost.analysis.compare import compare
from urdfpost.analysis.testpaths import great_circle_sweep, to_apt
from urdfpost.cli import main
from urdfpost.errors import UrdfpostError
from urdfpost.machine import load_machine
from urdfpost.planning.strategies import (
    ENTRY_POINT_GROUP,
    PLUGIN_RANK,
    STRATEGIES,
    Plan,
    Problem,
    StrategyTable,
    exact_plan,
    exact_selection,
    strategy,
)
from urdfpost.planning.strategies._registry import registered
from urdfpost.posting.options import PostOptions
from urdfpost.posting.whole import post

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE_SRC = ROOT / "examples" / "strategy_plugin" / "src"
BUILT_IN = ["none", "recursive", "branch-flip", "linear", "spline", "cone", "optimised"]
HOLD = "hold = urdfpost_hold:strategy_hold"
HOLD_ONLY = ("--strategies", "cone,hold")


def install(site: Path, *entry_points: str, name: str = "urdfpost_hold_test") -> None:
    """A distribution ``name`` declaring ``entry_points`` in the strategy group, in ``site``."""
    info = site / f"{name}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1.0\n")
    lines = "\n".join(entry_points)
    (info / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\n{lines}\n")


@pytest.fixture
def site(tmp_path, monkeypatch):
    """A site directory on ``sys.path`` with the example plug-in's source importable; every
    strategy the test registers is removed afterwards and the table looks again."""
    before = set(registered())
    site = tmp_path / "site"
    site.mkdir()
    monkeypatch.syspath_prepend(str(EXAMPLE_SRC))
    monkeypatch.syspath_prepend(str(site))
    yield site
    for name in set(registered()) - before:
        del STRATEGIES[name]
    sys.modules.pop("urdfpost_hold", None)
    monkeypatch.undo()
    STRATEGIES.reload_plugins()


@pytest.fixture
def sweep_apt(tmp_path) -> Path:
    path = tmp_path / "sweep1.apt"
    path.write_text(to_apt(great_circle_sweep(1.0)))
    return path


def test_a_plugin_is_listed_after_the_built_in_strategies_and_posts(site) -> None:
    install(site, HOLD)
    STRATEGIES.reload_plugins()
    assert list(STRATEGIES) == [*BUILT_IN, "hold"]  # its rank 900 is after optimised (70)
    result = post(great_circle_sweep(1.0), load_machine("dmu50"), PostOptions(strategy="hold"))
    assert result.report.strategy.name == "hold"
    assert result.verification.ok


def test_a_plugin_without_a_rank_comes_last(site, tmp_path) -> None:
    (site / "urdfpost_norank.py").write_text(
        "from urdfpost_hold import strategy_hold\n"
        "def strategy_norank(problem):\n"
        "    return strategy_hold(problem)\n"
    )
    install(site, HOLD, "aaa-norank = urdfpost_norank:strategy_norank")
    STRATEGIES.reload_plugins()
    assert list(STRATEGIES)[-2:] == ["hold", "aaa-norank"]
    assert PLUGIN_RANK > 900


def test_plugins_load_when_the_strategies_are_listed_not_before(site, caplog) -> None:
    install(site, HOLD, "broken = urdfpost_no_such_module:strategy")
    table = StrategyTable()
    with caplog.at_level(logging.WARNING, logger="urdfpost.planning.strategies._registry"):
        assert table["cone"] is STRATEGIES["cone"]  # a built-in name: nothing loaded
        assert "cone" in table
        assert not caplog.records
        names = list(table)
        assert "hold" in names and "broken" not in names
        assert len(caplog.records) == 1
        list(table)  # once: the warning is not repeated
        assert len(caplog.records) == 1


def test_a_broken_plugin_is_skipped_with_a_warning_naming_its_entry_point(site, caplog) -> None:
    install(
        site,
        HOLD,
        "broken = urdfpost_no_such_module:strategy",
        "notfn = urdfpost_hold:__all__",
    )
    with caplog.at_level(logging.WARNING, logger="urdfpost.planning.strategies._registry"):
        STRATEGIES.reload_plugins()
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 2, messages
    broken = next(m for m in messages if "broken" in m)
    assert "entry point broken = urdfpost_no_such_module:strategy" in broken
    assert "distribution urdfpost_hold_test 0.1.0" in broken
    assert "ModuleNotFoundError" in broken and "skipped" in broken
    notfn = next(m for m in messages if "notfn" in m)
    assert "is a list, expected a function Problem -> Plan" in notfn
    assert "hold" in STRATEGIES and "broken" not in STRATEGIES and "notfn" not in STRATEGIES


def test_a_name_clash_is_an_error_naming_both(site) -> None:
    install(site, "cone = urdfpost_hold:strategy_hold")
    with pytest.raises(UrdfpostError) as e:
        STRATEGIES.reload_plugins()
    message = str(e.value)
    assert "strategy 'cone' is registered twice" in message
    assert "urdfpost.planning.strategies.cone.strategy_cone" in message
    assert "entry point cone = urdfpost_hold:strategy_hold" in message
    assert STRATEGIES["cone"].__module__ == "urdfpost.planning.strategies.cone"


def test_two_plugins_of_one_name_clash(site) -> None:
    install(site, HOLD)
    install(site, "hold = urdfpost_norank2:f", name="other_dist")
    (site / "urdfpost_norank2.py").write_text("def f(problem):\n    raise AssertionError\n")
    with pytest.raises(UrdfpostError, match="'hold' is registered twice: entry point hold = "):
        STRATEGIES.reload_plugins()


def test_the_decorator_refuses_a_second_function_under_a_taken_name() -> None:
    with pytest.raises(UrdfpostError, match=r"'cone' is registered twice: urdfpost\.planning"):

        @strategy("cone", rank=1)
        def strategy_cone(problem: Problem) -> Plan:  # pragma: no cover - never called
            raise AssertionError


def test_the_cli_posts_and_compares_with_a_plugin(site, sweep_apt, tmp_path, capsys) -> None:
    install(site, HOLD)
    STRATEGIES.reload_plugins()
    out = tmp_path / "hold.h"
    assert main(["post", str(sweep_apt), "-m", "dmu50", "--strategy", "hold", "-o", str(out)]) == 0
    assert out.is_file()
    assert "strategy hold" in capsys.readouterr().out
    assert main(["compare", str(sweep_apt), "-m", "dmu50"]) == 0  # 'all' has the plug-in
    rows = [line.split()[0] for line in capsys.readouterr().out.splitlines()[3:] if line]
    assert rows[: len(BUILT_IN) + 1] == [*BUILT_IN, "hold"]


def test_a_clash_in_the_cli_is_exit_1_naming_both(site, sweep_apt, capsys) -> None:
    install(site, "cone = urdfpost_hold:strategy_hold")
    STRATEGIES._loaded = False  # as in a fresh process
    assert main(["compare", str(sweep_apt), "-m", "dmu50"]) == 1
    err = capsys.readouterr().err
    assert "strategy 'cone' is registered twice" in err and "entry point cone = " in err


def test_a_strategy_registered_by_a_script_is_accepted_by_the_cli(
    site, sweep_apt, tmp_path, capsys
) -> None:
    """Issue 18: a strategy added as one Python function worked from the API, but the command
    line's --strategy (its choices taken when the parser was built) rejected its name."""

    @strategy("script-exact", rank=950)
    def strategy_script_exact(problem: Problem) -> Plan:
        sel = exact_selection(problem, problem.toolpath)
        return exact_plan(problem, problem.toolpath, sel, [])

    assert "script-exact" in STRATEGIES
    out = tmp_path / "s.h"
    code = main(
        ["post", str(sweep_apt), "-m", "dmu50", "--strategy", "script-exact", "-o", str(out)]
    )
    assert code == 0, capsys.readouterr().err
    res = compare(great_circle_sweep(1.0), load_machine("dmu50"), ["script-exact"])
    assert res.outcomes[0].strategy == "script-exact" and res.outcomes[0].metrics is not None


def test_an_unknown_strategy_is_a_usage_error_listing_them(sweep_apt, capsys) -> None:
    assert main(["post", str(sweep_apt), "-m", "dmu50", "--strategy", "nope"]) == 2
    err = capsys.readouterr().err
    assert "--strategy: unknown 'nope'; expected one of none, recursive" in err
    assert "cone, optimised" in err


def test_a_plugin_installed_on_the_path_works_in_a_new_process(tmp_path, sweep_apt) -> None:
    site = tmp_path / "site"
    install(site, HOLD)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(EXAMPLE_SRC), env.get("PYTHONPATH", "")])
    run = subprocess.run(
        [sys.executable, "-m", "urdfpost", "compare", str(sweep_apt), "-m", "dmu50", *HOLD_ONLY],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    rows = {line.split()[0]: line.split()[1] for line in run.stdout.splitlines()[3:5]}
    assert rows == {"cone": "yes", "hold": "yes"}
