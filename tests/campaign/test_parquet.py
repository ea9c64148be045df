"""The campaign table written as Parquet reads back equal to the CSV table and to ``load``."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from ucontrol.campaign import load, load_campaign, run_campaign

pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")

CAMPAIGN = """
[campaign]
scene = "ball.toml"
duration = 0.1
seed = 5
runs = 2
metrics = ["max_penetration", "n_impacts", "final_energy"]
success = "n_impacts >= 1 and max_penetration < 1e-3"

[grid]
"robot.q0.0" = [0.05, 0.12]

[distributions]
"contacts.0.restitution" = { type = "uniform", low = 0.0, high = 0.95 }
"""


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 4-run campaign (2 of them raise: q0 inside the ground) written as CSV and Parquet."""
    from distributed import Client, LocalCluster

    tmp_path = tmp_path_factory.mktemp("parquet")
    path = tmp_path / "campaign.toml"
    path.write_text(textwrap.dedent(CAMPAIGN))
    out = tmp_path / "out"
    with (
        LocalCluster(
            n_workers=1,
            threads_per_worker=1,
            processes=False,
            dashboard_address=":0",
            silence_logs=50,
        ) as cluster,
        Client(cluster) as client,
    ):
        run_campaign(load_campaign(path), out, client=client, formats=("csv", "parquet"))
    return out


def _read_csv(path: Path, frame: pd.DataFrame) -> pd.DataFrame:
    """The CSV table with empty text cells kept as "" (NaN only in the numeric columns)."""
    numeric = [name for name in frame.columns if frame[name].dtype.kind == "f"]
    return pd.read_csv(path, keep_default_na=False, na_values={name: [""] for name in numeric})


def test_parquet_table_equals_load_and_csv(campaign_dir: Path) -> None:
    table = load(campaign_dir)
    parquet = pd.read_parquet(campaign_dir / "campaign.parquet")
    csv = _read_csv(campaign_dir / "campaign.csv", table)
    assert len(table) == 4
    assert set(table["status"]) == {"ok", "error"}  # text in `error` on some rows only
    # Exact equality, dtypes and column order included (floats round-trip through both).
    pd.testing.assert_frame_equal(parquet, table, check_exact=True)
    pd.testing.assert_frame_equal(parquet, csv, check_exact=True)
    assert parquet["success"].dtype == bool
    assert parquet["index"].dtype.kind == "i"
    assert parquet["error"].tolist() == csv["error"].tolist()
