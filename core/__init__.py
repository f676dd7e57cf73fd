"""The ground floor: the grid contract, the error hierarchy, file I/O, the recipe schema and the detailizer
protocol. It imports nothing else of the project."""

__version__ = "0.1.0"
