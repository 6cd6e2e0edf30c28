"""A study spread over processes by an existing engine (Dask's LocalCluster)
gives the study one process makes: `cassi.evaluate(shard=(K, N))` per task,
then `merge=N`."""

import csv
import pathlib

import pytest

import cassi

# small and quick: 4 synthetic 64×64 scenes, one per shard
COMMON = dict(synthetic=4, size=64, iterations=15)


def scores(folder: pathlib.Path):
    """outcomes.csv without its timing column."""
    with open(folder / "outcomes.csv", newline="") as f:
        return [row[:-1] for row in csv.reader(f)]


def without_timings(summary: dict) -> dict:
    drop = {"seconds", "total_seconds", "calibration_seconds_mean", "calibration_seconds_median"}
    if isinstance(summary, dict):
        return {k: without_timings(v) for k, v in summary.items() if k not in drop}
    if isinstance(summary, list):
        return [without_timings(v) for v in summary]
    return summary


def test_four_shards_on_a_dask_cluster_equal_the_one_process_study(tmp_path):
    from dask.distributed import Client, LocalCluster

    whole = cassi.evaluate(tmp_path / "whole", **COMMON)
    sharded = tmp_path / "sharded"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        futures = [client.submit(cassi.evaluate, str(sharded), shard=(k, 4), pure=False, **COMMON)
                   for k in range(4)]
        parts = client.gather(futures)
    # each shard ran its one scene: scene K (noise seed K)
    assert [p["scenes"] for p in parts] == [[f"synthetic_{k}"] for k in range(4)]
    for k in range(4):
        assert (sharded / "shards" / f"{k}-of-4" / "scenes" / f"synthetic_{k}.json").is_file()
    merged = cassi.evaluate(sharded, merge=4, **COMMON)
    assert without_timings(merged) == without_timings(whole)
    assert scores(sharded) == scores(tmp_path / "whole")
    for f in ["report.md", "summary.json", "parameters.csv", "figures/qualitative.png"]:
        assert (sharded / f).is_file(), f


def test_a_merge_before_every_shard_finished_names_the_missing_one(tmp_path):
    cassi.evaluate(tmp_path, shard="1/2", **COMMON)
    with pytest.raises(cassi.CassiError) as e:
        cassi.evaluate(tmp_path, merge=2, **COMMON)
    assert "shard 0/2" in str(e.value) and "synthetic_0" in str(e.value)
    assert not (tmp_path / "report.md").exists()


def test_bad_shards_are_refused(tmp_path):
    with pytest.raises(ValueError, match="K/N"):
        cassi.evaluate(tmp_path, shard="4/4", **COMMON)
    with pytest.raises(TypeError, match="shard"):
        cassi.evaluate(tmp_path, shard=4, **COMMON)
    with pytest.raises(ValueError, match="not both"):
        cassi.evaluate(tmp_path, shard=(0, 2), merge=2, **COMMON)
    with pytest.raises(ValueError, match="exactly one"):
        cassi.evaluate(tmp_path, size=64)
