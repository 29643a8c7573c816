"""The service tier's fixtures: a real ``millctl serve`` (embedded simulated node) per module."""

from tests.support.service import service

__all__ = ["service"]
