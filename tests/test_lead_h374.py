"""The lead's mends of stop 65: a study's --set leaves keep a byte not UTF-8 as the run's --set does."""

from tlm.config import read_set_value
from tlm.experiments.study import set_leaves


def test_a_set_item_holding_a_byte_not_utf8_sets_its_key_to_the_path_as_a_run_reads_it():
    path = "dir_\udcff/x.yaml"  # (os.fsdecode(b"dir_\xff/x.yaml"))
    assert set_leaves(f"scene={path}") == {"scene": path} == {"scene": read_set_value(path)}
    assert set_leaves("render={spp: 2, threads: 1}") == {"render.spp": 2, "render.threads": 1}
    assert set_leaves("scene=[unclosed") == {"scene": None}  # (YAML's refusal: its key alone, refused elsewhere)
