"""Mission files: YAML with units → validated pydantic models (see ``load_mission``)."""
