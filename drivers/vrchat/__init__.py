"""stylecast.drivers.vrchat"""
