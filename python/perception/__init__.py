"""The habitat's perception: objects located from their fiducial markers in the robot's cameras.

``locate`` finds an object's markers in one image and solves for its pose (OpenCV, no ROS);
``perception_node`` serves that as ``perception/locate`` on the robot side (``caretaker
perception``, a part of ``caretaker up``). Interfaces: ``caretaker_perception_msgs``.
"""
