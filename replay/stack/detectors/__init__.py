"""Range-anomaly detectors: the chi-square test, the BP dual threshold, ANFIS and its AQPSO-GA trainer."""
