"""stylecast.drivers.bvh"""
