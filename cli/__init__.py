"""The command line: the only code that prints for people and maps errors to exit codes."""
