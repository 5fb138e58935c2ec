"""A dataset reads with the tools researchers use, without drivestudio's code: pyarrow (and pandas) and Hugging Face
`datasets` on the Parquet shards the manifest lists, images decoded with OpenCV or PIL (docs/dataset.md, Reading).
The snippets here are the documented ones; the reference is drivestudio's own reader."""
import io
import json

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.dataset as pads
import pyarrow.parquet as pq
import pytest

from perception.shards import Dataset
from tests.perception.frames import dataset


@pytest.fixture(scope="module")
def root():
    return dataset()   # 120 highway frames in 10 episodes of 12 (shared with the perception tests)


def shard_files(root, split=None) -> list[str]:
    """The finished shards, as the manifest lists them (a shard not yet listed is not part of the dataset)."""
    manifest = json.loads((root / "manifest.json").read_text())
    return [str(root / s["file"]) for s in manifest["shards"] if split is None or s["split"] == split]


def test_pyarrow_reads_the_shards_and_opencv_decodes_the_images(root):
    ours = Dataset(root)
    table = pads.dataset(shard_files(root), format="parquet").to_table()          # every shard as one table
    assert table.num_rows == ours.frames() == 120
    assert table.schema.field("image_front").type == pa.binary()
    np.testing.assert_array_equal(table.column("angle").to_numpy(), ours.labels(columns=["angle"])["angle"])
    first = pq.read_table(shard_files(root)[0], columns=["image_front", "angle", "step"])   # one shard, some columns
    png = first.column("image_front")[3].as_py()
    rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    images, record = ours.reader(ours.shards[0]).row(3)
    assert rgb.shape == (210, 280, 3) and (rgb == images[0]).all()
    assert first.column("angle")[3].as_py() == pytest.approx(record["angle"]) and first.column("step")[3].as_py() == 3


def test_pandas_gets_the_labels_and_pil_decodes_the_images(root):
    pd = pytest.importorskip("pandas")
    from PIL import Image

    df = pq.read_table(shard_files(root, "train"), columns=None).to_pandas()
    labels = Dataset(root).labels("train")
    assert isinstance(df, pd.DataFrame) and len(df) == len(labels["angle"]) == 96
    np.testing.assert_allclose(df["dist_MM"].to_numpy(), labels["dist_MM"])
    assert df.groupby("episode")["step"].max().eq(11).all()
    img = np.asarray(Image.open(io.BytesIO(df["image_front"].iloc[0])).convert("RGB"))
    images, _ = Dataset(root).reader(Dataset(root).select("train")[0]).row(0)
    assert (img == images[0]).all()


def test_hugging_face_datasets_loads_the_splits(root, tmp_path, monkeypatch):
    hf = pytest.importorskip("datasets", reason="Hugging Face datasets is not installed")
    monkeypatch.setenv("HF_DATASETS_OFFLINE", "1")     # nothing to fetch: the parquet builder ships with datasets
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    splits = {"train": shard_files(root, "train"), "validation": shard_files(root, "val"),
              "test": shard_files(root, "test")}
    ds = hf.load_dataset("parquet", data_files=splits, cache_dir=str(tmp_path / "hf-cache"))
    assert {k: ds[k].num_rows for k in ds} == {"train": 96, "validation": 12, "test": 12}
    ours = Dataset(root)
    np.testing.assert_allclose(np.asarray(ds["test"]["toMarking_M"], dtype=np.float32),
                               ours.labels("test", ["toMarking_M"])["toMarking_M"])
    row = ds["validation"][5]
    rgb = cv2.cvtColor(cv2.imdecode(np.frombuffer(row["image_front"], np.uint8), cv2.IMREAD_COLOR),
                       cv2.COLOR_BGR2RGB)
    images, record = ours.reader(ours.select("val")[0]).row(5)
    assert (rgb == images[0]).all() and row["step"] == 5 and row["track"] == record["track"]
    torch_view = ds["train"].with_format("torch", columns=["angle", "dist_MM"])
    assert torch_view[0:4]["angle"].shape == (4,)
