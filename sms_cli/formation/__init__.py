"""Two spacecraft: servicer and client stepped as one Pinocchio model (capture, locked/shape view, laws)."""
