"""Files in and out: the contract Parquet traces and JSON, with provenance."""
