"""What a newcomer's mistakes meet on the command line: no abbreviated options, "did you mean"
for maps, methods, presets, choices and options, the right command to make a missing file,
and help that states every option's default."""

from __future__ import annotations

import argparse

import pytest

from pathpref.apps.cli import DefaultsFormatter, build_parser, main
from pathpref.planning.pomdp import DEFAULT_PRESET, PRESETS


def error_of(argv: list[str], capsys) -> str:
    """Run ``pathpref argv`` in-process; its exit status must be 2 with one stderr line."""
    try:
        rc = main(argv)
    except SystemExit as e:
        rc = e.code
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("pathpref: error: "), err
    return lines[0]


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


@pytest.mark.parametrize("argv,want", [
    (["evaluate", "--run", "3", "--db", "x.sqlite"],
     "unrecognized arguments: --run 3 (did you mean '--runs'?) (see 'pathpref evaluate --help')"),
    (["evaluate", "--inst", "1", "--db", "x.sqlite"],
     "unrecognized arguments: --inst 1 (did you mean '--instances'?)"),
    (["map", "info", "simple", "--jsn"],
     "unrecognized arguments: --jsn (did you mean '--json'?) (see 'pathpref map info --help')"),
    (["demo", "--pre", "paper"], "unrecognized arguments: --pre paper"),
])
def test_abbreviations_are_refused_naming_the_option(argv, want, capsys, tmp_path):
    assert want in error_of(argv, capsys)
    assert not (tmp_path / "x.sqlite").exists()


@pytest.mark.parametrize("argv,want", [
    (["map", "info", "ofice"], "no map named 'ofice' (did you mean 'office'?): give a built-in"),
    (["map", "info", "nowhere.json"], "no map named 'nowhere.json': give a built-in"),
    (["evaluate", "--methods", "path_pref", "--db", "x.sqlite"],
     "unknown method 'path_pref' (did you mean 'path_preference'?); choose from"),
    (["evaluate", "--methods", "telepathy", "--db", "x.sqlite"], "unknown method 'telepathy';"),
    (["evaluate", "--preset", "robus", "--db", "x.sqlite"],
     "invalid choice: 'robus' (did you mean 'robust'?) (choose from 'original', 'paper', "),
    (["demo", "--preset", "robust-chek"], "invalid choice: 'robust-chek' (did you mean "
     "'robust-check'?)"),
    (["render", "--method", "goal", "--out", "v.mp4"], "got 'goal' (did you mean 'goal_only'?)"),
    (["evlauate"], "invalid choice: 'evlauate' (did you mean 'evaluate'?)"),
])
def test_unknown_names_say_what_was_meant(argv, want, capsys):
    line = error_of(argv, capsys)
    assert want in line
    assert "''" not in line  # no doubled quotes round a name


@pytest.mark.parametrize("argv,want", [
    (["report", "missing.sqlite"], "run 'pathpref evaluate --db missing.sqlite' first"),
    (["replay", "missing.sqlite", "--participant", "p", "--trial", "1", "--out", "v.mp4"],
     "record trials first with 'pathpref study run STUDY --participant ID --db missing.sqlite'"),
    (["study", "export", "missing.sqlite", "--participant", "p", "--out", "o"],
     "record trials first with 'pathpref study run STUDY"),
])
def test_a_missing_file_names_the_command_that_makes_it(argv, want, capsys):
    line = error_of(argv, capsys)
    assert want in line
    assert ("evaluate" in line) == (argv[0] == "report")


def _leaves(parser: argparse.ArgumentParser, name: str = "pathpref"):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, sub in action.choices.items():
                yield from _leaves(sub, f"{name} {sub_name}")
    yield name, parser


def test_help_states_every_default():
    """Every optional option that is not a switch says its default in ``--help`` (the
    formatter's ``(default: X)`` or the help's own words)."""
    missing = []
    for name, parser in _leaves(build_parser()):
        fmt = DefaultsFormatter(prog=name)
        for a in parser._actions:
            if (not a.option_strings or a.required or a.help is argparse.SUPPRESS
                    or isinstance(a, argparse._StoreTrueAction | argparse._HelpAction
                                  | argparse._VersionAction)):
                continue
            if "default" not in fmt._get_help_string(a):
                missing.append(f"{name} {a.option_strings[0]}")
    assert missing == []


def test_preset_help_names_every_preset_and_the_default(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for preset in PRESETS:
        assert f"{preset} (" in text, preset
    assert f"(default: {DEFAULT_PRESET})" in text
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "main job" not in capsys.readouterr().out


def test_an_empty_database_names_both_commands_that_fill_one(capsys, tmp_path):
    from pathpref.experiments.store import ResultStore

    ResultStore(tmp_path / "empty.sqlite").close()
    line = error_of(["report", "empty.sqlite"], capsys)
    assert line == ("pathpref: error: empty.sqlite holds no episodes or study trials yet; run "
                    "'pathpref evaluate --db empty.sqlite' first (a sweep), or record trials "
                    "first with 'pathpref study run STUDY --participant ID --db empty.sqlite' "
                    "(docs/study.md)")
