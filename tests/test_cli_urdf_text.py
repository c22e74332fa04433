"""URDF given as text reads as the same file does: a byte-order mark, or an encoding declared
in the XML declaration (ISO-8859-1, with a non-ASCII joint name), in str and bytes alike."""

import numpy as np
import pytest

from jaxkin import serial

pytest.importorskip("yourdfpy")

URDF = """<?xml version="1.0" encoding="{encoding}"?>
<robot name="bras">
  <link name="base"/><link name="épaule"/><link name="outil"/>
  <joint name="hanché" type="revolute">
    <parent link="base"/><child link="épaule"/><origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-1.5" upper="1.5" velocity="2" effort="1"/>
  </joint>
  <joint name="coude" type="revolute">
    <parent link="épaule"/><child link="outil"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" velocity="2" effort="1"/>
  </joint>
</robot>
"""


def same_chain(a, b):
    assert a.joint_names == b.joint_names == ("hanché", "coude")
    for field in ("screws", "home", "lower", "upper", "velocity"):
        np.testing.assert_array_equal(np.asarray(getattr(a, field)), np.asarray(getattr(b, field)))


@pytest.mark.parametrize(
    ("encoding", "bom"), [("UTF-8", b"\xef\xbb\xbf"), ("ISO-8859-1", b""), ("iso-8859-1", b"")]
)
def test_urdf_text_with_bom_or_latin1_reads_as_its_file(tmp_path, encoding, bom):
    raw = bom + URDF.format(encoding=encoding).encode(encoding)
    path = tmp_path / "bras.urdf"
    path.write_bytes(raw)
    from_file = serial.from_urdf(path, "outil")
    text = raw.decode("utf-8-sig" if bom else encoding)  # as a user reads it: a str
    if bom:
        text = "\ufeff" + text  # open(..., encoding="utf-8") keeps the mark
    same_chain(serial.from_urdf(text, "outil"), from_file)
    same_chain(serial.from_urdf(raw, "outil"), from_file)
