"""stylecast.drivers.vmc"""
