"""hmap.Params: presets, names, attributes, the library's validation and messages."""

import pytest

import hmap


def test_presets_hold_the_papers_values():
    # SPEC / paper section V: cell 0.05 / 0.25 m, range 0.8-5 / 1.2-25 m, d_n 0.4 / 0.9 m.
    indoor, outdoor = hmap.Params("indoor"), hmap.Params("outdoor")
    assert indoor.get("map.cell_size") == 0.05
    assert outdoor.get("map.cell_size") == 0.25
    assert (indoor.get("map.min_range"), indoor.get("map.max_range")) == (0.8, 5.0)
    assert (outdoor.get("map.min_range"), outdoor.get("map.max_range")) == (1.2, 25.0)
    assert indoor.get("ground.expansion_distance") == 0.4
    assert outdoor.get("ground.expansion_distance") == 0.9
    assert hmap.Params() == outdoor
    # Between them for a LiDAR in a building: the outdoor preset at 0.1 m and 10 m, the cell 1 % of the range.
    room = hmap.Params("room")
    assert (room.get("map.cell_size"), room.get("map.max_range"), room.get("map.min_range")) == (0.1, 10.0, 1.2)
    assert room.get("ground.expansion_distance") == 0.9
    assert set(hmap.Params.presets()) == {"indoor", "room", "outdoor"}


def test_unknown_preset_raises_the_library_message():
    with pytest.raises(ValueError, match=r"unknown preset 'garden' \(expected indoor, room or outdoor\)"):
        hmap.Params("garden")


def test_every_parameter_readable_by_name_and_attribute():
    p = hmap.Params("indoor")
    names = hmap.Params.names()
    assert "map.cell_size" in names and "slam.max_iterations" in names and "ground.seed" in names
    assert len(names) == len(set(names))
    for name in names:
        section, field = name.split(".", 1)
        assert getattr(getattr(p, section), field) == p.get(name), name
    assert p.map.cell_size == 0.05


def test_set_by_name_and_by_attribute():
    p = hmap.Params()
    p.set("map.cell_size", 0.2)
    assert p.get("map.cell_size") == 0.2
    p.map.max_range = 40
    assert p.get("map.max_range") == 40.0
    p.ground.iterations = 99.6  # an integer field rounds, as the CLI's --set does
    assert p.get("ground.iterations") == 100.0
    assert p != hmap.Params()


def test_unknown_name_raises_and_names_it():
    p = hmap.Params()
    with pytest.raises(ValueError, match=r"unknown parameter 'map.cell_sise' \(known: map.cell_size, "):
        p.set("map.cell_sise", 0.2)
    with pytest.raises(ValueError, match="unknown parameter 'map.nope'"):
        p.get("map.nope")
    with pytest.raises(AttributeError, match="no parameter map.cell_sise"):
        p.map.cell_sise
    with pytest.raises(AttributeError, match="'Params' has no attribute 'mapp'"):
        p.mapp


def test_out_of_range_value_raises_and_leaves_params_unchanged():
    p = hmap.Params()
    with pytest.raises(hmap.Error, match=r"parameter map.cell_size = -1 is out of its range .* m"):
        p.set("map.cell_size", -1)
    assert p.get("map.cell_size") == 0.25
    with pytest.raises(ValueError, match="occupancy.ground_gain = 0.7 is out of its range"):
        p.occupancy.ground_gain = 0.7
    with pytest.raises(ValueError, match="'map.cell_size' needs a finite number"):
        p.set("map.cell_size", float("nan"))
    # A rule between parameters: min_range must stay below max_range.
    with pytest.raises(ValueError, match="map.max_range"):
        p.set("map.min_range", 30)
    assert p.get("map.min_range") == 1.2
    p.update({"map.min_range": 30, "map.max_range": 50})  # together they are valid
    assert (p.map.min_range, p.map.max_range) == (30.0, 50.0)


def test_describe_and_yaml():
    d = hmap.Params.describe("map.cell_size")
    assert d["unit"] == "m" and d["default"] == 0.25 and d["range"].startswith(("[", "("))
    yaml = hmap.Params("indoor").to_yaml()
    assert "map.cell_size: 0.05" in yaml
