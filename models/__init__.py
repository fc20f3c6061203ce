"""stylecast.models — see ARCHITECTURE.md in the README."""
