"""Benchmark pipelines of the RaidEnv paper (PROTOCOLS.md §11): ``python -m experiments.benchmark1`` and
``python -m experiments.benchmark2``, each writing a resumable run folder (see ``trainers.runfolder``)."""
