"""Jobs over files: one recording to one stream (``convert``), and folders in batch."""
