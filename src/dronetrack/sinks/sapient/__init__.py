"""dronetrack as a SAPIENT (BSI Flex 335 v2.0) edge node, and a minimal fusion node.

- ``link``: the TCP link to a fusion node, in a thread of its own, that never blocks
  the tracking loop;
- ``node``: what the edge node sends (DetectionReports, Alerts, StatusReports) and
  does (look-at Tasks);
- ``listen``: the minimal fusion node of ``dronetrack sapient-listen``.

Needs the optional extra ``[sapient]``.
"""
