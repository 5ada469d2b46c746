"""Monte-Carlo campaigns: case sampling, execution, the resumable store, summaries."""
