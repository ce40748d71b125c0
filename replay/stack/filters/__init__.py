"""Filters of the cooperative-localization stack: the cubature rule, the CKF and the adaptive CKF."""
