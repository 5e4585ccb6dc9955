"""The recorder's schema cache: the same message definitions and hashes as the typestore's,
written at set-up only, and ignored (computed in memory) when stale or unreadable."""

import json

import pytest

from activetrack_bringup import bag
from activetrack_ros.graph import GRAPH_TOPICS

pytestmark = pytest.mark.ros


@pytest.fixture
def cache(tmp_path, monkeypatch):
    path = tmp_path / "share" / "bag_schemas.json"
    monkeypatch.setattr(bag, "SCHEMA_CACHE", path)
    monkeypatch.setattr(bag, "_schemas_in_memory", {})
    return path


def test_cache_equals_the_typestore(cache):
    store = bag.graph_typestore()
    schemas = bag.graph_schemas()
    assert not cache.exists()  # nothing written at run time
    assert bag.graph_schemas(write_cache=True) == schemas  # set-up writes it
    assert cache.exists()
    assert set(schemas) == set(GRAPH_TOPICS.values())
    for msgtype, (msgdef, rihs01) in schemas.items():
        assert msgdef == store.generate_msgdef(msgtype, ros_version=2)[0]
        assert rihs01 == store.hash_rihs01(msgtype)
        assert rihs01.startswith("RIHS01_")
    assert bag.graph_schemas() == schemas  # second call: from the file


def test_stale_or_broken_cache_is_not_trusted(cache, monkeypatch):
    good = bag.graph_schemas(write_cache=True)
    data = json.loads(cache.read_text())
    data["key"] = "stale"
    data["schemas"]["msgs_defs/msg/TrackArray"] = ["wrong", "RIHS01_wrong"]
    cache.write_text(json.dumps(data))
    monkeypatch.setattr(bag, "_schemas_in_memory", {})
    assert bag.graph_schemas() == good
    monkeypatch.setattr(bag, "_schemas_in_memory", {})
    cache.write_text("{not json")
    assert bag.graph_schemas() == good
    assert cache.read_text() == "{not json"  # left alone: set-up rewrites it
