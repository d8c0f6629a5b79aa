"""The record of the files nlos_cl wrote in a folder is visible and says what it is
(files-written-by-nlos_cl.json); a folder an earlier version wrote (the hidden
.nlos_cl-written.json) is still read, and its record moves to the new name at the next write."""
import json
import os

import pytest

from nlos_cl.core.errors import InputError
from nlos_cl.io.safe_write import (
    MANIFEST,
    OLD_MANIFEST,
    require_writable,
    write_text,
    written_by_nlos_cl,
)


def test_the_record_is_visible_and_named_for_what_it_lists(tmp_path):
    write_text(tmp_path / "page.md", "text", what="--out")
    assert sorted(os.listdir(tmp_path)) == ["files-written-by-nlos_cl.json", "page.md"]
    assert not MANIFEST.startswith(".")
    assert set(json.loads((tmp_path / MANIFEST).read_text())) == {"page.md"}


def test_a_folder_an_earlier_version_wrote_is_still_ours_and_moves_to_the_new_name(tmp_path):
    import hashlib
    old = tmp_path / "fig.png"
    old.write_bytes(b"png bytes")
    (tmp_path / OLD_MANIFEST).write_text(json.dumps({"fig.png": {
        "size": 9, "sha256": hashlib.sha256(b"png bytes").hexdigest()}}))
    assert written_by_nlos_cl(old)
    require_writable(old, what="--out")  # replaceable without --force, as before
    write_text(tmp_path / "page.md", "text", what="--out")
    assert sorted(os.listdir(tmp_path)) == ["fig.png", MANIFEST, "page.md"]
    assert set(json.loads((tmp_path / MANIFEST).read_text())) == {"fig.png", "page.md"}
    assert written_by_nlos_cl(old)


@pytest.mark.parametrize("name", [MANIFEST, OLD_MANIFEST])
def test_neither_record_can_be_written_over_as_a_file(tmp_path, name):
    with pytest.raises(InputError, match="nlos_cl's record"):
        write_text(tmp_path / name, "{}", what="--out")
