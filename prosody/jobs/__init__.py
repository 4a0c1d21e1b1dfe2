"""Jobs over files: one recording to one stream (``convert``), folders in batch, and videos tracked."""
