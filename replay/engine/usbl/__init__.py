"""LBL/USBL in the engine: epochs grouped from buoy observations, and positioned by every method."""
