"""The wire: the message envelope and its validation (:mod:`.messages`), signing and rejections
(:mod:`.signing`), topic names and ids (:mod:`.topics`). Never pickle."""
