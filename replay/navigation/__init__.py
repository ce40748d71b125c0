"""The navigation review of one vehicle: dead reckoning restarted at GPS fixes, drift at fixes, bottom lock, series.

Pure numpy on columns; `review.review_vehicle` is the entry point.
"""

from .review import NavigationConfig, NavigationReview, NavigationScore, review_vehicle, scores

__all__ = ["NavigationConfig", "NavigationReview", "NavigationScore", "review_vehicle", "scores"]
