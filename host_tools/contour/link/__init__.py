"""Host link to a contour drive: transports (serial, CAN) and one client.

from contour.link import connect
with connect(port="/dev/pts/3") as drive:        # or can="slcan:/dev/pts/4", node=1
    print(drive.identify())
"""

from contour.link.client import Client, DriveError, connect
from contour.link.options import connect_from_args, link_options
from contour.link.transport import LinkError

__all__ = ["Client", "DriveError", "LinkError", "connect", "connect_from_args", "link_options"]
