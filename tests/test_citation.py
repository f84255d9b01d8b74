"""Licence and citation (issue 31): LICENSE is MIT, CITATION.cff is valid CFF 1.2.0 and cites the
seed paper, pyproject.toml and the README agree with both.

The CFF check is written here against the CFF 1.2.0 schema's rules (citation-file-format.github.io,
``schema.json``: the required keys, the top-level keys it allows, a reference's required keys,
the patterns of ``cff-version``, DOI, date, URL and ISSN, and the integer fields), so the test
needs no network and no validator package; ``check_cff`` is tested on broken copies below, so it
is known to fail where it should.
"""

from __future__ import annotations

import copy
import re
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

yaml = pytest.importorskip("yaml")  # the [test] extra installs pyyaml

ROOT = Path(__file__).resolve().parents[1]

#: CFF 1.2.0: the keys a file must have, and every key it may have at its top level
REQUIRED = ("authors", "cff-version", "message", "title")
TOP_KEYS = set(REQUIRED) | {
    "abstract", "commit", "contact", "date-released", "doi", "identifiers", "keywords",
    "license", "license-url", "preferred-citation", "references", "repository",
    "repository-artifact", "repository-code", "type", "url", "version",
}  # fmt: skip
#: a reference (``references`` items, ``preferred-citation``) must have these
REFERENCE_REQUIRED = ("authors", "title", "type")
#: the reference types this file may use (a subset of the schema's 47)
REFERENCE_TYPES = {"article", "software", "book", "conference-paper", "report", "thesis", "generic"}
#: fields the schema types as integers
REFERENCE_INTS = ("volume", "start", "end", "year", "month", "pages")
PERSON_KEYS = {
    "family-names", "given-names", "name-particle", "name-suffix", "affiliation", "email",
    "orcid", "website", "alias", "address", "city", "country", "region", "post-code", "tel",
    "fax",
}  # fmt: skip
PATTERNS = {
    "cff-version": r"^1\.2\.0$",
    "doi": r"^10\.\d{4,9}(\.\d+)?/[A-Za-z0-9:/_;\-\.\(\)\[\]\\]+$",
    "date": r"^[0-9]{4}-(0[1-9]|1[012])-(0[1-9]|[12][0-9]|3[01])$",
    "url": r"^(https|http|ftp|sftp)://.+",
    "issn": r"^\d{4}-\d{3}[\dxX]$",
}


def _authors(where: str, authors) -> list[str]:
    if not isinstance(authors, list) or not authors:
        return [f"{where}.authors: must be a non-empty list"]
    errors = []
    for i, a in enumerate(authors):
        if not isinstance(a, dict):
            errors.append(f"{where}.authors[{i}]: must be a person or an entity")
        elif "name" in a:  # an entity
            if not isinstance(a["name"], str) or not a["name"]:
                errors.append(f"{where}.authors[{i}].name: must be a non-empty string")
        elif not a or set(a) - PERSON_KEYS:
            errors.append(f"{where}.authors[{i}]: unknown keys {sorted(set(a) - PERSON_KEYS)}")
    return errors


def _match(where: str, kind: str, value) -> list[str]:
    if not isinstance(value, str) or not re.match(PATTERNS[kind], value):
        return [f"{where} = {value!r}: not a valid {kind}"]
    return []


def _reference(where: str, ref) -> list[str]:
    if not isinstance(ref, dict):
        return [f"{where}: must be a mapping"]
    errors = [f"{where}: missing required key {k!r}" for k in REFERENCE_REQUIRED if k not in ref]
    if "type" in ref and ref["type"] not in REFERENCE_TYPES:
        errors.append(f"{where}.type = {ref['type']!r}: not a reference type")
    if "authors" in ref:
        errors += _authors(where, ref["authors"])
    for k in REFERENCE_INTS:
        if k in ref and (not isinstance(ref[k], int) or isinstance(ref[k], bool)):
            errors.append(f"{where}.{k} = {ref[k]!r}: must be an integer")
    if isinstance(ref.get("month"), int) and not 1 <= ref["month"] <= 12:
        errors.append(f"{where}.month = {ref['month']!r}: must be 1-12")
    for k, kind in (("doi", "doi"), ("url", "url"), ("issn", "issn"), ("date-released", "date")):
        if k in ref:
            errors += _match(f"{where}.{k}", kind, ref[k])
    return errors


def check_cff(data) -> list[str]:
    """Every way ``data`` (a parsed CITATION.cff) breaks the CFF 1.2.0 rules above; [] if none."""
    if not isinstance(data, dict):
        return ["the file must be a mapping"]
    errors = [f"missing required key {k!r}" for k in REQUIRED if k not in data]
    errors += [f"unknown top-level key {k!r}" for k in sorted(set(data) - TOP_KEYS)]
    if "cff-version" in data:
        errors += _match("cff-version", "cff-version", data["cff-version"])
    if "authors" in data:
        errors += _authors("", data["authors"])
    if data.get("type", "software") not in ("software", "dataset"):
        errors.append(f"type = {data['type']!r}: must be software or dataset")
    for k, kind in (("doi", "doi"), ("url", "url"), ("repository-code", "url")):
        if k in data:
            errors += _match(k, kind, data[k])
    if "date-released" in data:
        errors += _match("date-released", "date", data["date-released"])
    if "preferred-citation" in data:
        errors += _reference("preferred-citation", data["preferred-citation"])
    refs = data.get("references", [])
    if not isinstance(refs, list):
        errors.append("references: must be a list")
    else:
        for i, r in enumerate(refs):
            errors += _reference(f"references[{i}]", r)
    return errors


def _cff() -> dict:
    return yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))


def test_license_is_mit():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License")
    assert "Permission is hereby granted, free of charge" in text


def test_citation_cff_is_valid_cff_1_2():
    data = _cff()
    assert check_cff(data) == []
    # a YAML date would be a date object, not the string the schema asks for
    assert isinstance(data["date-released"], str)


def test_citation_cites_the_seed_paper():
    data = _cff()
    paper = data["preferred-citation"]
    assert paper["doi"] == "10.3390/machines11080783"  # Machines 2023, 11(8), 783
    assert (paper["journal"], paper["volume"], paper["start"], paper["year"]) == (
        "Machines",
        11,
        783,
        2023,
    )
    assert paper["title"].startswith("Numerical and Machine-Aided Experimental Models")
    assert [a["family-names"] for a in paper["authors"]][0] == "Cirelli"
    assert any(r.get("doi") == paper["doi"] for r in data["references"])


@pytest.mark.parametrize(
    "breakage, expected",
    [
        (lambda d: d.pop("message"), "missing required key 'message'"),
        (lambda d: d.update({"cff-version": "1.1.0"}), "cff-version = '1.1.0'"),
        (lambda d: d.update({"titel": "x"}), "unknown top-level key 'titel'"),
        (lambda d: d["preferred-citation"].pop("authors"), "missing required key 'authors'"),
        (lambda d: d["preferred-citation"].update({"doi": "doi.org/10.3390/x"}), "valid doi"),
        (lambda d: d["references"][0].update({"volume": "11"}), "volume = '11'"),
        (lambda d: d.update({"date-released": "2026-13-01"}), "not a valid date"),
        (lambda d: d.update({"authors": []}), "non-empty list"),
    ],
)
def test_the_checker_finds_a_broken_file(breakage, expected):
    data = copy.deepcopy(_cff())
    breakage(data)
    assert any(expected in e for e in check_cff(data)), check_cff(data)


def test_pyproject_and_readme_agree_with_the_citation():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    data = _cff()
    assert project["license"] == data["license"] == "MIT"
    assert project["version"] == str(data["version"])
    assert project["authors"][0]["name"] == data["authors"][0]["name"]
    assert data["preferred-citation"]["url"] in project["urls"].values()
    readme = (ROOT / "README.md").read_text()
    citing = readme.split("## Citing", 1)[1].split("\n## ", 1)[0]
    assert "CITATION.cff" in citing and "10.3390/machines11080783" in citing
