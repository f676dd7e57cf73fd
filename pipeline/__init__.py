"""The content flow: regions, detailize, mesh, engines, export, build, cache, executors, manifest."""
