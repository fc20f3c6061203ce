"""stylecast.drivers — see ARCHITECTURE.md in the README."""
