"""Live: audio that is still arriving in, face frames out as each is known.

- :mod:`prosody.live.converter`: :class:`~prosody.live.converter.LiveConverter` (push audio, get frames), the
  audio sources (files, pipes, microphones) and :class:`~prosody.live.converter.FrameRecorder`;
- :mod:`prosody.live.session`: :class:`~prosody.live.session.StreamSession`, a whole live session (input,
  converter, page server, link senders, recorder) as ``prosody stream`` runs it, from Python;
- :mod:`prosody.live.server`: the page and WebSocket server that draws the face in browsers;
- :mod:`prosody.live.senders`: Live Link Face and VMC senders over UDP.
"""
