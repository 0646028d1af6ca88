"""The release's three records agree: the version pyproject.toml names has its own section in
CHANGELOG.md (under an "Unreleased" section kept at the top, above the releases newest first,
with what changed for users and what to migrate), and CITATION.cff names the same version."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _version() -> str:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def _releases() -> list[str]:
    """The CHANGELOG's second-level headings, in order (``Unreleased``, ``0.3.0``, ...)."""
    heads = re.findall(r"^## (\S+)", (ROOT / "CHANGELOG.md").read_text(), flags=re.M)
    assert heads, "CHANGELOG.md has no release sections"
    return heads


def _key(v: str) -> tuple[int, ...]:
    return tuple(int(x) for x in v.split("."))


def test_the_changelog_has_a_section_for_the_version_pyproject_names():
    heads = _releases()
    assert heads[0] == "Unreleased", heads[:2]
    assert heads[1] == _version(), f"the newest release section is {heads[1]}, " \
        f"pyproject.toml names {_version()}"
    versions = heads[1:]
    assert all(re.fullmatch(r"\d+\.\d+\.\d+", v) for v in versions), versions
    assert versions == sorted(versions, key=_key, reverse=True) and len(set(versions)) == len(
        versions), versions


def test_the_release_section_says_what_changed_and_what_to_migrate():
    text = (ROOT / "CHANGELOG.md").read_text()
    section = text.split(f"\n## {_version()}", 1)[1].split("\n## ", 1)[0]
    assert "\n### What changed for users\n" in section
    assert "\n### What to migrate\n" in section


def test_citation_names_the_same_version():
    cff = (ROOT / "CITATION.cff").read_text()
    found = re.findall(r"^version:\s*\"?([^\"\s]+)\"?\s*$", cff, flags=re.M)
    assert found == [_version()], found
