"""stylecast: live motion restyling. Subpackages: motion, drivers, models, daemon, viewer."""

__version__ = "0.1.0"
