"""The MPEG-4 FAP data model and its files: the FAP table, streams with per-frame masks, the .fap reader
and writer, the exporters and the inspector. Imports nothing else of the package but its errors."""
