"""Every built-in scenario, robot and instrument preset loads to exactly the objects it loaded to before the
schemas were made declarative (issue 31): the reference was written by ``builtin_reference.py`` on main."""

import json

from builtin_reference import REFERENCE, loaded_builtins


def test_builtins_load_to_the_reference_objects():
    reference = json.loads(REFERENCE.read_text())
    loaded = loaded_builtins()
    assert loaded.keys() == reference.keys()
    for group, expected in reference.items():
        if isinstance(expected, dict):
            assert loaded[group].keys() == expected.keys(), group
            for name, objects in expected.items():
                assert loaded[group][name] == objects, f"{group}/{name}"
        else:
            assert loaded[group] == expected, group
