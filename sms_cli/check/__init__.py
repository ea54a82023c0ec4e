"""Requirements (``requirements:`` in mission files), regression baselines and JUnit output (``sms check``)."""
