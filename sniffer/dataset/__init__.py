"""The fleet dataset: captures as a partitioned Parquet dataset that many sniffers append to.

    DIR/dataset.json                                     what this is: format, schema version, tables
    DIR/frames/link=drives/date=2026-11-25/CAPTURE.parquet   one file per capture segment, table and partition
    DIR/points/link=.../date=.../CAPTURE.parquet
    DIR/annotations/link=.../date=.../CAPTURE.parquet
    DIR/_manifest/CAPTURE.json                           one per capture taken in: source, size, mtime, sha256
    DIR/_staging/...                                     files being written (readers skip `_` folders)

layout.py: the folder, dataset.json, the manifest, a capture's name and link;
ingest.py: one capture file through one Session into the dataset (dataset/sink.py
writes the files); query.py: DuckDB views over it, the named queries, output.
Schemas: sniffer.formats.schemas.  Nothing is ever rewritten: a capture adds its own
files (written under `_staging`, renamed into place, its manifest entry last).
"""
