"""stylecast.daemon — see ARCHITECTURE.md in the README."""
