"""The face, in one room: lips from phones (visemes coarticulated by dominance functions) or from the spectrum
(the acoustic mouth model), facial expressions and emotional states (PAD) blended onto them, and the face layer
that puts them together for a recording (:func:`prosody.motion.face.layer.make_face`)."""
