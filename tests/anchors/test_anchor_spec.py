"""spec/FORMAT.md §17 documents every chunk the anchor encoder writes, as the code registers it."""

from __future__ import annotations

import re

from csgs_codec.format import CHUNK_TYPES, read_layers
from tests.anchors.helpers import encoded
from tests.conftest import REPO

SPEC = (REPO / "spec" / "FORMAT.md").read_text(encoding="utf-8")
SECTION = SPEC[SPEC.index("## 17. Anchor scenes"):]


def written_codes() -> set[str]:
    return {e.type for e in read_layers(encoded().data, layers="base").toc}


def test_every_anchor_chunk_has_a_section_in_17():
    headings = re.findall(r"^### 17\.\d+ (.*)$", SECTION, re.M)
    documented = {code for h in headings for code in re.findall(r"`(\w{4})`", h)}
    assert written_codes() - {"GEOM", "SEML", "SEMR"} <= documented


def test_the_registry_rows_pointing_to_17_match_the_code_registry():
    rows = re.findall(r"^\| `(\w{4})` \| (\w+) \| (yes|no) \| §17\.[\d.]+ \| (.*) \|$", SPEC,
                      re.M)
    # vorg is written only for scenes that carry view origins (what csgs train makes).
    assert {code for code, *_ in rows} == (written_codes() | {"vorg"}) - {"GEOM", "SEML",
                                                                         "SEMR"}
    for code, layer, critical, description in rows:
        info = CHUNK_TYPES[code]
        assert (layer, critical == "yes", description) == (info.layer.label, info.critical,
                                                           info.description)
