"""The ``harmonic-tamp-nav`` command line (``navigation.render.main``): a picture on success,
one ``error:`` line and status 2 on every bad input, never a traceback."""

from __future__ import annotations

import cv2
import pytest

from navigation import render


def test_help_documents_every_option(capsys):
    with pytest.raises(SystemExit) as info:
        render.main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for option in ("--goal", "--region", "--inflation", "--out", "--size", "--starts", "--seed", "--max-steps",
                   "--scale", "--levels"):
        assert option in out, option


def test_renders_simple_with_descents(tmp_path, capsys):
    out = tmp_path / "nf.png"
    assert render.main(["simple", "--region", "b", "--size", "64", "--starts", "4", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "trajectories: 4/4 reached the goal" in text and f"wrote {out}" in text
    image = cv2.imread(str(out))
    assert image is not None and max(image.shape[:2]) == 64


@pytest.mark.parametrize("argv, needle", [
    (["--goal", "1e400", "0"], "finite"),
    (["--goal", "nan", "1"], "finite"),
    (["--size", "8"], "between 32 and 8000"),
    (["--inflation", "-1"], ">= 0"),
    (["--starts", "100000000"], "between 0 and 10000"),  # allocated 68 GiB before the bound
    (["--seed", "-1"], ">= 0"),  # numpy's ValueError traceback before
    (["--max-steps", "10000000"], "between 0 and 1000000"),
    (["--levels", "100000"], "between 0 and 1000"),
    (["--out", "nf.jpg"], ".png"),
    (["--scale", "cubic"], "invalid choice"),
])
def test_bad_arguments_exit_2_with_a_usage_error(argv, needle, capsys):
    with pytest.raises(SystemExit) as info:
        render.main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


@pytest.mark.parametrize("argv, needle", [
    (["simple", "--out", "/nonexistent-dir/nf.png"], "cannot write"),
    (["simple", "--region", "zz"], "zz"),
    (["simple", "--inflation", "1e308"], "cannot shrink"),
    (["no-such-world.json"], "no-such-world.json"),
])
def test_product_and_io_errors_are_one_error_line(argv, needle, capsys, tmp_path):
    if "--out" not in argv:
        argv = argv + ["--out", str(tmp_path / "nf.png")]
    assert render.main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], err


def test_a_goal_outside_free_space_is_refused(capsys, tmp_path):
    import navigation

    world = navigation.load_world("simple")
    c = world.obstacles[0].center
    assert render.main(["simple", "--goal", str(c[0]), str(c[1]), "--out", str(tmp_path / "nf.png")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err
