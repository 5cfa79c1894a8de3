"""Assembly robot: plan execution and bidding (paper sections 2.1 and 2.3)."""
