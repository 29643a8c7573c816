"""The mill's drives behind one boundary (:mod:`.base`): the millbus node, or standard CiA 402 drives."""

from millctl.drives.base import DriveInfo, DriveLimitsRefused, DrivesBackend, DrivesBatch, LimitsState

__all__ = ["DriveInfo", "DriveLimitsRefused", "DrivesBackend", "DrivesBatch", "LimitsState"]
