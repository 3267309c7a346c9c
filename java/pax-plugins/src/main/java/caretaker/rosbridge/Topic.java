package caretaker.rosbridge;

import com.google.gson.JsonObject;

/**
 * A ROS topic on a {@link Ros} connection: subscribe, advertise, publish. Subscriptions and
 * advertisements survive reconnects (the connection re-sends them). Thread-safe.
 */
public final class Topic {
    private final Ros ros;
    private final String name;
    private final String type;
    private final int throttleRate;
    private final int queueLength;
    /** Guards the two ids below. */
    private final Object lock = new Object();
    private String subscribeId;
    private String advertiseId;

    /**
     * @param ros the connection
     * @param name the topic, e.g. {@code /affordance_template_server/status}
     * @param type the message type, e.g. {@code std_msgs/msg/Bool}
     */
    public Topic(Ros ros, String name, String type) {
        this(ros, name, type, 0, 0);
    }

    /**
     * @param ros the connection
     * @param name the topic
     * @param type the message type
     * @param throttleRate least milliseconds between messages the server sends (0 = all)
     * @param queueLength messages the server queues while throttling (0 = none)
     */
    public Topic(Ros ros, String name, String type, int throttleRate, int queueLength) {
        if (name == null || name.isEmpty()) {
            throw new IllegalArgumentException("topic name must not be empty");
        }
        this.ros = ros;
        this.name = name;
        this.type = type;
        this.throttleRate = throttleRate;
        this.queueLength = queueLength;
    }

    /** @return the topic name */
    public String getName() {
        return name;
    }

    /** @return the message type */
    public String getType() {
        return type;
    }

    /** @return whether {@link #subscribe} was called and not undone */
    public boolean isSubscribed() {
        synchronized (lock) {
            return subscribeId != null;
        }
    }

    /** @return whether this topic is advertised */
    public boolean isAdvertised() {
        synchronized (lock) {
            return advertiseId != null;
        }
    }

    /**
     * Subscribes; messages go to {@code callback} on the connection's callback thread. A second
     * call replaces the first subscription. Works while disconnected: sent on (re)connect.
     *
     * @param callback receives each message
     */
    public void subscribe(TopicCallback callback) {
        synchronized (lock) {
            if (subscribeId != null) {
                ros.unsubscribe(subscribeId);
            }
            subscribeId = Protocol.OP_SUBSCRIBE + ":" + name + ":" + ros.nextId();
            ros.subscribe(subscribeId, name, type, throttleRate, queueLength, callback);
        }
    }

    /** Ends the subscription; does nothing if not subscribed. */
    public void unsubscribe() {
        synchronized (lock) {
            if (subscribeId != null) {
                ros.unsubscribe(subscribeId);
                subscribeId = null;
            }
        }
    }

    /** Advertises this topic so it can be published; idempotent. */
    public void advertise() {
        synchronized (lock) {
            if (advertiseId == null) {
                advertiseId = Protocol.OP_ADVERTISE + ":" + name + ":" + ros.nextId();
                JsonObject request = request(Protocol.OP_ADVERTISE, advertiseId);
                request.addProperty(Protocol.FIELD_TYPE, type);
                request.addProperty(Protocol.FIELD_LATCH, false);
                request.addProperty(Protocol.FIELD_QUEUE_SIZE, 100);
                ros.advertise(advertiseId, request);
            }
        }
    }

    /** Withdraws the advertisement; does nothing if not advertised. */
    public void unadvertise() {
        synchronized (lock) {
            if (advertiseId != null) {
                ros.unadvertise(advertiseId, request(Protocol.OP_UNADVERTISE, advertiseId));
                advertiseId = null;
            }
        }
    }

    /**
     * Publishes, advertising first if needed.
     *
     * @param message the message to publish
     * @throws RosException not connected, or the send failed
     */
    public void publish(Message message) {
        advertise();
        JsonObject request = request(Protocol.OP_PUBLISH, Protocol.OP_PUBLISH + ":" + name + ":" + ros.nextId());
        request.add(Protocol.FIELD_MSG, message.toJsonObject());
        ros.send(request);
    }

    private JsonObject request(String op, String id) {
        JsonObject request = new JsonObject();
        request.addProperty(Protocol.FIELD_OP, op);
        request.addProperty(Protocol.FIELD_ID, id);
        request.addProperty(Protocol.FIELD_TOPIC, name);
        return request;
    }
}
