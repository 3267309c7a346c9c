"""bridge: the habitat side of the link. The rosbridge v2 server (and the command ledger), on rclpy.

Nothing here knows procedures: the procedure side (``pride``, with its JPype host of the Java
plugins) reaches this package only over the rosbridge protocol.
"""
