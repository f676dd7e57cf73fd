"""Evaluation: the protocol, the metrics, Cls, evaluate, ablation tables and benchmarking."""
