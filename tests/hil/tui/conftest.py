"""The TUI tier's fixtures: real services in subprocesses, one with fault injection."""

from tests.support.tui import fault_service, service_dir

__all__ = ["fault_service", "service_dir"]
