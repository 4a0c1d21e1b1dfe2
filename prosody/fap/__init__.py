"""The MPEG-4 FAP data model and its files: the FAP table, streams with per-frame masks, the .fap reader
and writer, the other formats' writers and readers, the inspector, and recorded motion's files (what the
tracker writes and the recorded-motion condition reads). Imports nothing else of the package but its errors."""
