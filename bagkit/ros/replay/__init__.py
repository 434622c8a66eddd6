"""The player (:class:`~bagkit.ros.replay.player.Player`): publishers, the publishing loop and
the control services."""
