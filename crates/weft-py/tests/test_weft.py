"""Tests of the `weft` Python module (run by .ci/run after building and installing the wheel).

The scene is the C example's (crates/weft-capi/tests/c/host_scene.json): a small cloth over a
box the host moves, and two strands the host gives.
"""

import pathlib
import threading

import numpy as np
import pytest

import weft

ROOT = pathlib.Path(__file__).resolve().parents[3]
SCENE = ROOT / "crates/weft-capi/tests/c/host_scene.json"

FACES = [0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
         2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6]


def box(frame):
    """The 0.2 m box centred at (0, 0.1 + 0.01 frame, 0): corners by bits of k."""
    y = 0.1 + 0.01 * frame
    p = [[0.1 if k & 1 else -0.1, y + (0.1 if k & 2 else -0.1), 0.1 if k & 4 else -0.1]
         for k in range(8)]
    return np.array(p), np.array(FACES, dtype=np.uint32).reshape(-1, 3)


def strands():
    p = [[-0.05 if c == 0 else 0.05, 0.6 - 0.025 * k, 0.025 * k] for c in range(2) for k in range(5)]
    return np.array(p), np.array([0, 5, 10], dtype=np.uint32)


def host_graph():
    g = weft.Graph.load(SCENE)
    for f in range(5):
        g.feed("boxmesh", "mesh", box(f), frame=f)
    g.feed("tuft", "curves", strands())
    return g


def test_a_bad_graph_file_lists_every_problem_with_node_field_and_line():
    text = ('{"format": "weft-graph", "version": 1,\n'
            ' "nodes": {"a": {"type": "value.float", "params": {"value": "x"}},\n'
            '           "b": {"type": "no.such"}},\n'
            ' "outputs": {"y": "a.out"}}')
    with pytest.raises(weft.LoadError) as e:
        weft.Graph.from_string(text, "broken.json")
    problems = e.value.problems
    assert len(problems) == 2
    bad = [p for p in problems if p["node"] == "a"][0]
    assert "value" in bad["field"] and bad["line"] == 2
    assert "broken.json" in str(e.value)


def test_listing_nodes_outputs_and_parameters():
    g = weft.Graph.load(SCENE)
    assert "grid" in g.nodes and "solve" in g.nodes
    assert g.outputs == {"center": "vec3", "gain": "float", "scene": "scene", "strands": "curves"}
    d = g.describe("grid")
    assert d["type"] == "geo.grid" and d["outputs"] == [("mesh", "mesh")]
    assert g.params("grid")["nx"] == 5
    nx = [p for p in d["params"] if p["name"] == "nx"][0]
    assert nx["kind"] == {"int": {"min": 2, "max": None}} or "int" in str(nx["kind"])


def test_parameters_are_validated_and_named_in_errors():
    g = weft.Graph.load(SCENE)
    g.set("damping", "coefficient", 0.2)
    assert g.params("damping")["coefficient"] == 0.2
    with pytest.raises(weft.GraphError) as e:
        g.set("damping", "coefficient", -1.0)
    assert e.value.node == "damping" and "coefficient" in e.value.field
    with pytest.raises(weft.GraphError) as e:
        g.set("damping", "nope", 1)
    assert e.value.node == "damping"
    assert g.params("damping")["coefficient"] == 0.2  # nothing changed


def test_fed_data_round_trips_exactly_and_drives_the_solver():
    g = host_graph()
    positions, offsets = g.pull("strands", 0)
    assert np.array_equal(positions, strands()[0]) and list(offsets) == [0, 5, 10]
    g.feed("gain", "out", 2.5)
    assert g.pull("gain", 0) == 2.5
    assert g.unfeed("gain", "out") and g.pull("gain", 0) == 1.0
    assert ("boxmesh", "mesh", [0, 1, 2, 3, 4]) in g.fed
    first = None
    for f in range(1, 5):
        scene = g.pull("scene", f)
        assert set(scene) == {"cloth", "pins", "hair", "roots", "block", "contacts"}
        cloth, hair = scene["cloth"], scene["hair"]
        assert cloth["positions"].shape == (25, 3) and cloth["triangles"].shape == (32, 3)
        assert list(hair["offsets"]) == [0, 5, 10]
        first = first if first is not None else cloth["positions"].copy()
    # The held roots are where the host put them; the tips fell.
    held = [0, 5]
    assert np.array_equal(hair["positions"][held], strands()[0][held])
    assert hair["positions"][4, 1] < strands()[0][4, 1]
    assert not np.array_equal(first, cloth["positions"])
    # Determinism: the same graph and data again give the same bits.
    again = host_graph().pull("scene", 4)
    assert np.array_equal(again["cloth"]["positions"], cloth["positions"])
    stats = g.stats()
    assert any(n["node"] == "solve" and n["steps"] == 4 for n in stats["nodes"])


def test_bad_host_data_is_refused_and_changes_nothing():
    g = weft.Graph.load(SCENE)
    p, t = box(0)
    with pytest.raises(weft.GraphError, match="vertex 8"):
        g.feed("boxmesh", "mesh", (p, np.array([[0, 1, 8]], dtype=np.uint32)))
    bad = p.copy()
    bad[1, 1] = np.nan
    with pytest.raises(weft.GraphError, match="non-finite"):
        g.feed("boxmesh", "mesh", (bad, t))
    with pytest.raises(weft.GraphError, match="fewer than 2"):
        g.feed("tuft", "curves", (strands()[0], np.array([0, 1, 10], dtype=np.uint32)))
    with pytest.raises(weft.GraphError, match="fewer than 2"):  # no wrap-around in the check
        g.feed("tuft", "curves", (strands()[0], np.array([0, 0xFFFFFFFF, 10], dtype=np.uint32)))
    with pytest.raises(weft.GraphError):
        g.feed("solve", "scene", 1.0)
    with pytest.raises(weft.GraphError):
        g.pull("nope", 1)
    assert g.fed == []


def test_an_evaluation_error_names_the_node_and_frame():
    g = weft.Graph.load(SCENE)
    # A cloth of 3 vertices: the pins (vertices 0 and 4) name what is wrong.
    g.feed("grid", "mesh", (np.zeros((3, 3)), np.array([[0, 1, 2]], dtype=np.uint32)))
    with pytest.raises(weft.EvalError) as e:
        g.pull("scene", 1)
    assert e.value.node == "pins" and "vertex 4" in str(e.value)
    # A cloth of 25 vertices all at one point: its triangles have no area.
    g.unfeed("grid", "mesh")
    _, triangles = g.pull_port("grid", "mesh", 0)
    g.feed("grid", "mesh", (np.zeros((25, 3)), triangles))
    with pytest.raises(weft.EvalError) as e:
        g.pull("scene", 1)
    assert (e.value.node, e.value.frame) == ("solve", 0)
    assert "triangle 0" in str(e.value) and "zero rest area" in str(e.value)


def test_another_thread_can_interrupt_a_pull():
    g = host_graph()
    stop = g.interrupter()
    stop.set()
    with pytest.raises(weft.Interrupted):
        g.pull("scene", 2)
    stop.reset()
    assert g.pull("scene", 1)["cloth"]["positions"].shape == (25, 3)
    # While a pull runs (the GIL is released), a thread sets the request.
    timer = threading.Timer(0.05, stop.set)
    timer.start()
    try:
        g.pull("scene", 400)
    except weft.Interrupted as e:
        assert e.frame is not None
    timer.join()
