"""The provenance section: the run record, versions and the documents the report was built from."""

from __future__ import annotations

import datetime as _dt

from robotcal.io.results.run_folder import REPORT_NAME, Table
from robotcal.report import installed_version
from robotcal.report.page import _FOLD_ROWS, _block, _facts, _Page, _Table


def _provenance(page: _Page) -> dict:
    record = page.record
    blocks = (
        _facts(record, caption="run record", source="run.json", skip=("versions", "scenario.settings"))
        if record
        else [_block("note", text="No run.json: this run was not recorded by robotcal run.")]
    )
    versions = {}
    for name in ("cpa/parameters.json", "uncertainty/parameters.json"):
        found = (page.json(name) or {}).get("provenance", {})
        if isinstance(found, dict) and isinstance(found.get("versions"), dict):
            versions.update({str(k): str(v) for k, v in found["versions"].items()})
    if isinstance(record.get("versions"), dict):
        versions.update({str(k): str(v) for k, v in record["versions"].items()})
    versions.setdefault("robotcal (this report)", installed_version())
    blocks.append(
        _Table(
            header=["software", "version"],
            rows=[[k, v] for k, v in versions.items()],
            caption="Versions",
            text_columns=frozenset({0, 1}),
        )
    )
    rows = []
    for name in sorted(n for n in page.result.documents if n != REPORT_NAME):
        document = page.result.documents[name]
        if isinstance(document, Table):
            rows.append([name, "CSV", f"{len(document.rows)} rows of {len(document.header)} columns"])
        elif isinstance(document, dict):
            rows.append([name, "JSON", f"{len(document)} top-level entries"])
        else:
            rows.append([name, "figure" if name.endswith(".png") else "binary file", ""])
    blocks.append(
        _Table(
            header=["document", "kind", "contents"],
            rows=rows,
            caption="The documents of the run this report was built from",
            text_columns=frozenset({0, 1, 2}),
            code_columns=frozenset({0}),
            fold=f"{len(rows)} documents of the run (show)" if len(rows) > _FOLD_ROWS else "",
        )
    )
    folder = page.result.folder
    return {
        "present": True,
        "blocks_": blocks,
        "generated": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
        "version": installed_version(),
        "folder": str(folder) if folder is not None else None,
    }
