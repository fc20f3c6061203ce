"""stylecast.drivers.trackers.trackers"""
