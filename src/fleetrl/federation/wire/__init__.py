"""The wire: the message envelope and its validation (:mod:`.messages`, over :mod:`.rejections`), signing
(:mod:`.signing`), topic names and ids (:mod:`.topics`). Never pickle."""
