"""Every X.parquet in the given directories, read back with pyarrow, equals X.csv: the same columns in the same
order, the same rows, every value equal to its CSV cell read exactly (floats to the last bit, an empty cell a
null), zstd pages; and pandas reads it to the same shape."""
import csv
import math
import pathlib
import sys

import pandas as pd
import pyarrow.parquet as pq


def same(cell, value):
    if cell == "":
        return value is None
    if isinstance(value, bool):
        return cell == ("true" if value else "false")
    if isinstance(value, int):
        return int(cell) == value
    if isinstance(value, float):
        x = float(cell)
        return x == value or (math.isnan(x) and math.isnan(value))
    return cell == value


def check(csv_path, parquet_path):
    with open(csv_path, newline="") as f:
        rows = list(csv.reader(f))
    header, rows = rows[0], rows[1:]
    table = pq.read_table(parquet_path)
    assert table.column_names == header, (parquet_path, table.column_names, header)
    assert table.num_rows == len(rows), (parquet_path, table.num_rows, len(rows))
    for j, name in enumerate(header):
        for i, value in enumerate(table.column(j).to_pylist()):
            assert same(rows[i][j], value), f"{parquet_path}: row {i}, column {name}: csv {rows[i][j]!r}, parquet {value!r}"
    meta = pq.ParquetFile(parquet_path).metadata
    codecs = {meta.row_group(g).column(c).compression for g in range(meta.num_row_groups) for c in range(meta.num_columns)}
    assert codecs <= {"ZSTD"}, (parquet_path, codecs)
    assert pd.read_parquet(parquet_path).shape == (len(rows), len(header))
    return len(rows), len(header)


def main(dirs):
    n = 0
    for d in dirs:
        for p in sorted(pathlib.Path(d).glob("*.parquet")):
            rows, cols = check(p.with_suffix(".csv"), p)
            print(f"{p}: {rows} rows × {cols} columns equal to {p.with_suffix('.csv').name}")
            n += 1
    assert n > 0, "no Parquet file found"


if __name__ == "__main__":
    main(sys.argv[1:])
