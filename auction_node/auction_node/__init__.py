"""Online error correction: mismatch detection and missing-tile auctions (paper section 2.3)."""
