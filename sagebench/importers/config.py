"""Output names of the InteriorGS importer, apart from the importer (so a command line reads them cheaply); its
settings are sagebench/settings/import_interiorgs.py."""

from __future__ import annotations

REPORT_FILE = "interiorgs_import.json"  # what the import matched and measured; marks a directory it wrote
OCCUPANCY_PICTURE = "occupancy_check.png"
