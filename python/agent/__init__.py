"""Assistant agents as principals: ``caretaker agent``, an MCP server with an agent's rights and no more."""
