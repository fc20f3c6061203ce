"""stylecast.drivers.serial"""
