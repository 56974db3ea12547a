"""One client's connection to the endpoint, from accept to close.

session (ClientSession: the socket, the conversation on it and the connection's life; SessionOwner, what it needs
from the endpoint), web_session (WebSocketSession: the same life over WebSocket, a ClientSession whose frames go out
as binary messages and whose close is a handshake; it builds on session, never the other way), output
(SessionOutput, the way out: direct sends, a bounded queue and its writer), calls (CallRoom and ClientCalls, the
threads of the clients' ROS calls), queues (OutgoingQueue and ByteBudget, bounded and pure) and sockets (socket
helpers shared with the ROS side and the Python client).

This file imports nothing, so that a module of it (the pure queues, the sockets the client uses) loads without the
sessions and their ROS publisher: import from the modules."""
