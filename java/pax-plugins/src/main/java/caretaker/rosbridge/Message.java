package caretaker.rosbridge;

import com.google.gson.JsonObject;

/** A ROS message as rosbridge carries it: a JSON object with the message's fields. */
public class Message extends JsonWrapper {
    /** An empty message (every field takes its ROS default). */
    public Message() {
        super(new JsonObject());
    }

    /** @param json the message fields (copied) */
    public Message(JsonObject json) {
        super(json);
    }

    /** @param json the message as JSON text */
    public Message(String json) {
        super(json);
    }
}
