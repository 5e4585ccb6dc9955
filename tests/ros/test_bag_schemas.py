"""The recorder's schema cache: the same message definitions and hashes as the typestore's,
rebuilt when the cache is stale or unreadable."""

import json

import pytest

from activetrack_bringup import bag
from activetrack_ros.graph import GRAPH_TOPICS

pytestmark = pytest.mark.ros


@pytest.fixture
def cache(tmp_path, monkeypatch):
    path = tmp_path / "share" / "bag_schemas.json"
    monkeypatch.setattr(bag, "SCHEMA_CACHE", path)
    return path


def test_cache_equals_the_typestore(cache):
    store = bag.graph_typestore()
    schemas = bag.graph_schemas()
    assert cache.exists()
    assert set(schemas) == set(GRAPH_TOPICS.values())
    for msgtype, (msgdef, rihs01) in schemas.items():
        assert msgdef == store.generate_msgdef(msgtype, ros_version=2)[0]
        assert rihs01 == store.hash_rihs01(msgtype)
        assert rihs01.startswith("RIHS01_")
    assert bag.graph_schemas() == schemas  # second call: from the file


def test_stale_or_broken_cache_is_rebuilt(cache):
    good = bag.graph_schemas()
    data = json.loads(cache.read_text())
    data["key"] = "stale"
    data["schemas"]["msgs_defs/msg/TrackEstimate"] = ["wrong", "RIHS01_wrong"]
    cache.write_text(json.dumps(data))
    assert bag.graph_schemas() == good
    cache.write_text("{not json")
    assert bag.graph_schemas() == good
    assert json.loads(cache.read_text())["key"] != "stale"
