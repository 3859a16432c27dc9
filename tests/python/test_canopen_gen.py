"""The CANopen object dictionary definition (protocol/canopen.toml) and what
protocol/gen_canopen.py makes of it: the generated files are fresh, the EDS
loads in the python `canopen` master and describes the same objects."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import canopen
import pytest
from contour import canopen_od

ROOT = Path(__file__).resolve().parents[2]
GEN = ROOT / "protocol" / "gen_canopen.py"
EDS = ROOT / "protocol" / "contour.eds"


def _gen():
    spec = importlib.util.spec_from_file_location("canopen_gen_script", GEN)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_generated_files_are_fresh():
    r = subprocess.run([sys.executable, str(GEN), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_check_detects_a_stale_file(tmp_path):
    gen = _gen()
    for rel, text in gen.generate(gen.load()).items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    assert gen.main(["--check", "--out", str(tmp_path)]) == 0
    eds = tmp_path / "protocol" / "contour.eds"
    eds.write_text(eds.read_text().replace("DefaultValue=0x20192", "DefaultValue=0x20191"))
    assert gen.main(["--check", "--out", str(tmp_path)]) == 1


def test_generator_rejects_a_broken_definition(tmp_path):
    gen = _gen()
    bad = tmp_path / "bad.toml"
    text = (ROOT / "protocol" / "canopen.toml").read_text()
    bad.write_text(text.replace('type = "u16"', 'type = "u17"', 1))
    with pytest.raises(gen.SpecError, match="unknown type"):
        gen.load(bad)


def test_eds_loads_in_canopen_and_matches_the_table():
    od = canopen.import_od(str(EDS), node_id=3)
    assert od[0x1000].default == 0x00020192
    assert od[0x1000].data_type == canopen.objectdictionary.UNSIGNED32
    assert od[0x1018][2].name == "Product code"
    assert od[0x1029][1].max == 2
    for index, sub, name, typ, access, default in canopen_od.ENTRIES:
        var = (
            od[index]
            if isinstance(od[index], canopen.objectdictionary.Variable)
            else od[index][sub]
        )
        assert var.name == name
        assert var.access_type == access
        if typ != "str":
            node = 3 if (index, sub) in canopen_od.NODE_RELATIVE else 0
            assert var.default == default + node, hex(index)
        else:
            assert var.data_type == canopen.objectdictionary.VISIBLE_STRING


def test_eds_describes_the_pdos_and_csp_objects():
    od = canopen.import_od(str(EDS), node_id=3)
    assert od[0x1400][1].default == 0x200 + 3 and od[0x1800][1].default == 0x180 + 3
    assert od[0x1402][1].default == 0x80000400  # RPDO3 starts invalid
    assert od[0x1601][0].default == 2 and od[0x1601][2].default == 0x607A0020
    assert od[0x1A01][2].default == 0x60640020
    assert od[0x1803][5].name == "Event timer" and 4 not in od[0x1803].subindices
    assert od[0x6064].pdo_mappable and od[0x607A].pdo_mappable
    assert not od[0x1000].pdo_mappable
    assert od[0x6064].data_type == canopen.objectdictionary.INTEGER32
    assert od[0x60C2][2].data_type == canopen.objectdictionary.INTEGER8
    assert od[0x60C2][2].default == -3 and od[0x60C2][2].min == -6
    text = EDS.read_text()
    assert "NrOfRXPDO=4" in text and "NrOfTXPDO=4" in text
