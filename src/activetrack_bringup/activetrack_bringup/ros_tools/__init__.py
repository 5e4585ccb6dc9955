"""``activetrack ros ...``: small stand-ins for the ROS 2 command line (not on PyPI) that work on
any graph, ours or not: ``graph``, ``echo``, ``hz``, ``param``, ``tf`` (docs/ros-tools.md).

They are generic over topics and types: names and types come from the live graph
(introspection), message classes from their type names, never from a table of the graph's
own types. Each command joins the DDS domain with a node of its own (``--domain``, default
``ROS_DOMAIN_ID`` or 0; discovery as ``ROS_AUTOMATIC_DISCOVERY_RANGE`` says) and resolves
relative names in ``--namespace``.
"""
