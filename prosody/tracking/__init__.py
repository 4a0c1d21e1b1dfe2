"""Motion recorded from video: a face tracker's head, brow and mouth curves, in the talking-heads formats."""
