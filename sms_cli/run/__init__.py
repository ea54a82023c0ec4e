"""``sms run``: orchestration of the stages a mission configures."""
