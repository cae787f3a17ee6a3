"""Every command line refuses bad numbers with one ``error:`` line and status 2
(``navigation._argtypes``): exact checks of the types, then each command's options."""

from __future__ import annotations

import argparse
import importlib

import pytest

from navigation._argtypes import integer, number, positive, seed, world_name


@pytest.mark.parametrize("kind, text, value", [
    (integer(0), "0", 0), (integer(0), "17", 17), (integer(1, 3), "3", 3), (integer(None, 5), "-9", -9),
    (integer(), "-4", -4), (seed, "0", 0), (number(), "-1.5", -1.5), (number(0.0), "0", 0.0),
    (number(0.0, 0.1), "0.1", 0.1), (positive, "1e-9", 1e-9), (positive, "2", 2.0),
])
def test_accepts_values_within_bounds(kind, text, value):
    assert kind(text) == value and type(kind(text)) is type(value)


@pytest.mark.parametrize("kind, text, needle", [
    (integer(0), "-1", "must be an integer >= 0, got '-1'"),
    (integer(1, 3), "4", "must be an integer between 1 and 3, got '4'"),
    (integer(None, 5), "6", "must be an integer <= 5"),
    (integer(0), "1.5", "expected an integer, got '1.5'"),
    (integer(0), "ten", "expected an integer"),
    (seed, "-1", ">= 0"),
    (number(), "nan", "must be a finite number, got 'nan'"),
    (number(), "1e400", "finite"),
    (number(), "-inf", "finite"),
    (number(), "x", "expected a number, got 'x'"),
    (number(0.0), "-0.1", "must be a finite number >= 0, got '-0.1'"),
    (number(0.0, 0.1), "0.2", ">= 0 and <= 0.1"),
    (positive, "0", "must be a finite number > 0, got '0'"),
    (positive, "inf", "> 0"),
    (positive, "nan", "> 0"),
])
def test_refuses_values_outside_bounds_naming_bound_and_value(kind, text, needle):
    with pytest.raises(argparse.ArgumentTypeError) as info:
        kind(text)
    assert needle in str(info.value)


def test_world_name_loads_the_world_and_returns_the_text(tmp_path):
    assert world_name("simple") == "simple"
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    for text in ("no-such-world", str(bad)):
        with pytest.raises(argparse.ArgumentTypeError) as info:
            world_name(text)
        assert text in str(info.value) and "\n" not in str(info.value)


def test_type_names_describe_the_bound():
    assert integer(32, 8000).__name__ == "integer between 32 and 8000"
    assert positive.__name__ == "a finite number > 0"


# (module, argv) pairs: one bad number per option that takes one
BAD = [
    ("tamp.run", ["simple", "--seed", "-1"]), ("tamp.run", ["simple", "--max-time", "nan"]),
    ("service.sim_node", ["--speed", "0"]), ("service.sim_node", ["--duration", "nan"]),
    ("service.sim_node", ["--seed", "-2"]),
    ("service.cli", ["demo", "--rate", "inf"]), ("service.cli", ["run", "--watchdog", "-1"]),
    ("navigation.render", ["--starts", "-1"]), ("navigation.render", ["--inflation", "nan"]),
    ("benchmarks.evaluation", ["--jobs", "0"]), ("benchmarks.evaluation", ["--random", "-1"]),
    ("benchmarks.evaluation", ["--max-time", "-5"]), ("benchmarks.evaluation", ["--rrt-draws", "0"]),
    ("benchmarks.executive", ["--noise", "0.5"]), ("benchmarks.executive", ["--jitter", "-1"]),
    ("benchmarks.executive", ["--repeat", "0"]), ("benchmarks.control", ["--relax", "-1"]),
    ("benchmarks.control", ["--starts", "0"]), ("benchmarks.perception", ["--noise", "nan"]),
    ("benchmarks.perception", ["--goals", "0"]), ("benchmarks.harmonic_tree", ["--repeats", "0"]),
    ("benchmarks.navigation", ["--sizes", "0"]), ("benchmarks.sim", ["--sizes", "-3"]),
    ("benchmarks.online", ["--sizes", "x"]), ("benchmarks.soak", ["--window", "nan"]),
    ("benchmarks.service", ["--seconds", "0"]), ("benchmarks.service", ["--cases", "fast"]),
    # worlds that do not load (a traceback from the worker before)
    ("benchmarks.evaluation", ["--shared", "no-such-world"]), ("benchmarks.ltl", ["--world", "no-such-world"]),
    ("benchmarks.soak", ["--world", "no-such-world"]), ("benchmarks.perception", ["--worlds", "no-such-world"]),
    ("benchmarks.navigation", ["--shared", "no-such-world"]), ("benchmarks.sim", ["--shared", "no-such-world"]),
    ("benchmarks.service", ["--world", "no-such-world"]),
]


@pytest.mark.parametrize("module, argv", BAD, ids=[f"{m} {' '.join(a)}" for m, a in BAD])
def test_every_command_refuses_a_bad_number_before_doing_work(module, argv, capsys):
    main = importlib.import_module(module).main
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert "error:" in last and argv[-1] in last, err
