"""stylecast.viewer — see ARCHITECTURE.md in the README."""
