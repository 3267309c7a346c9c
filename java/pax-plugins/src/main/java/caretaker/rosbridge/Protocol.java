package caretaker.rosbridge;

/** The rosbridge v2 vocabulary: every op and field name this client sends or reads. */
public final class Protocol {
    private Protocol() {
    }

    /** Field naming the operation of every message. */
    public static final String FIELD_OP = "op";
    /** Field naming an interaction, echoed by the server in replies. */
    public static final String FIELD_ID = "id";
    /** Topic name field. */
    public static final String FIELD_TOPIC = "topic";
    /** Message or service type field. */
    public static final String FIELD_TYPE = "type";
    /** Message body field of publish. */
    public static final String FIELD_MSG = "msg";
    /** Service name field. */
    public static final String FIELD_SERVICE = "service";
    /** Service request field. */
    public static final String FIELD_ARGS = "args";
    /** Service response values (an object, or a string describing a failure). */
    public static final String FIELD_VALUES = "values";
    /** Service response outcome. */
    public static final String FIELD_RESULT = "result";
    /** Subscription throttle in milliseconds. */
    public static final String FIELD_THROTTLE_RATE = "throttle_rate";
    /** Subscription queue length. */
    public static final String FIELD_QUEUE_LENGTH = "queue_length";
    /** Advertisement queue size. */
    public static final String FIELD_QUEUE_SIZE = "queue_size";
    /** Latching of an advertisement. */
    public static final String FIELD_LATCH = "latch";
    /** Compression requested for a subscription. */
    public static final String FIELD_COMPRESSION = "compression";
    /** Server-side timeout of a service call in seconds. */
    public static final String FIELD_TIMEOUT = "timeout";
    /** Fragment payload. */
    public static final String FIELD_DATA = "data";
    /** Fragment index. */
    public static final String FIELD_NUM = "num";
    /** Fragment count. */
    public static final String FIELD_TOTAL = "total";

    /** Authentication: HMAC over the fields below. */
    public static final String FIELD_MAC = "mac";
    /** Authentication: who connects. */
    public static final String FIELD_CLIENT = "client";
    /** Authentication: the server connected to. */
    public static final String FIELD_DEST = "dest";
    /** Authentication: a random string, new per connection. */
    public static final String FIELD_RAND = "rand";
    /** Authentication: the client's Unix time in seconds. */
    public static final String FIELD_T = "t";
    /** Authentication: the access level asked for. */
    public static final String FIELD_LEVEL = "level";
    /** Authentication: the end of validity, Unix seconds. */
    public static final String FIELD_END = "end";
    /** Authentication: a bearer token instead of a MAC. */
    public static final String FIELD_TOKEN = "token";

    /** Authenticate; the first message on a bridge that requires it. */
    public static final String OP_AUTH = "auth";
    /** Publish a message (both directions). */
    public static final String OP_PUBLISH = "publish";
    /** Subscribe to a topic. */
    public static final String OP_SUBSCRIBE = "subscribe";
    /** Unsubscribe from a topic. */
    public static final String OP_UNSUBSCRIBE = "unsubscribe";
    /** Advertise a topic. */
    public static final String OP_ADVERTISE = "advertise";
    /** Withdraw an advertisement. */
    public static final String OP_UNADVERTISE = "unadvertise";
    /** Call a service. */
    public static final String OP_CALL_SERVICE = "call_service";
    /** Reply to a service call. */
    public static final String OP_SERVICE_RESPONSE = "service_response";
    /** One part of a fragmented message. */
    public static final String OP_FRAGMENT = "fragment";
    /** Server status report (only after set_level on servers that implement it). */
    public static final String OP_STATUS = "status";

    /** WebSocket close code the bridge uses to refuse a client (RFC 6455 policy violation). */
    public static final int CLOSE_POLICY_VIOLATION = 1008;
}
