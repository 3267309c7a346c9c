package caretaker.rosbridge;

import java.time.Duration;
import java.time.Instant;
import java.util.concurrent.Executors;
import java.util.concurrent.ScheduledExecutorService;
import java.util.concurrent.TimeUnit;
import java.util.concurrent.atomic.AtomicReference;
import java.util.function.Consumer;

/**
 * Keeps a connection honest: pings it every interval, says it is quiet as soon as nothing (no
 * frame, no pong) came from the server for a few intervals, and reports it silent (to be dropped)
 * when nothing came for longer than the timeout. Its own thread, because a ping may wait behind a
 * send on a slow link.
 */
final class Keepalive implements AutoCloseable {
    /** Pings unanswered before the server is said to be quiet: one lost pong is not news. */
    static final int QUIET_INTERVALS = 3;

    private final ScheduledExecutorService thread;
    private final long timeoutNanos;
    private final long quietNanos;
    private final Runnable ping;
    private final Consumer<Instant> silent;
    private final Consumer<Instant> quiet;
    private final Runnable heardAgain;
    private volatile long heardNanos = System.nanoTime();
    private volatile Instant heardAt = Instant.now();
    /** When the server was last heard, while it is quiet (said so once); null while it is heard. */
    private final AtomicReference<Instant> quietSince = new AtomicReference<>();

    /**
     * @param name the thread's name
     * @param interval how often to ping
     * @param timeout how long the server may stay silent
     * @param ping sends one ping (runs on this thread)
     * @param silent told the time the server was last heard when it stayed silent too long
     * @param quiet told the time the server was last heard when nothing came for {@link #QUIET_INTERVALS}
     *        intervals (or the timeout, if shorter): long before the connection is given up
     * @param heardAgain told when a quiet server is heard again (on the thread that heard it: be quick)
     */
    Keepalive(String name, Duration interval, Duration timeout, Runnable ping, Consumer<Instant> silent,
            Consumer<Instant> quiet, Runnable heardAgain) {
        this.timeoutNanos = timeout.toNanos();
        this.quietNanos = Math.min(interval.toNanos() * QUIET_INTERVALS, timeoutNanos);
        this.ping = ping;
        this.silent = silent;
        this.quiet = quiet;
        this.heardAgain = heardAgain;
        this.thread = Executors.newSingleThreadScheduledExecutor(runnable -> {
            Thread worker = new Thread(runnable, name);
            worker.setDaemon(true);
            return worker;
        });
        thread.scheduleWithFixedDelay(this::tick, interval.toNanos(), interval.toNanos(), TimeUnit.NANOSECONDS);
    }

    /** Something came from the server (or a new connection opened): it is alive now. */
    void heard() {
        heardNanos = System.nanoTime();
        heardAt = Instant.now();
        if (quietSince.get() != null && quietSince.getAndSet(null) != null) { // one frame says so, once
            heardAgain.run();
        }
    }

    /** @return when the server was last heard, while it is quiet; null while it is heard */
    Instant quietSince() {
        return quietSince.get();
    }

    /** @return {@link System#nanoTime()} when the server was last heard */
    long lastHeardNanos() {
        return heardNanos;
    }

    /** @return when the server was last heard */
    Instant lastHeard() {
        return heardAt;
    }

    private void tick() {
        long heardBefore = heardNanos;
        long silentFor = System.nanoTime() - heardBefore;
        if (silentFor > timeoutNanos) {
            silent.accept(heardAt);
            return;
        }
        if (silentFor > quietNanos) {
            Instant since = heardAt;
            if (quietSince.compareAndSet(null, since)) {
                if (heardNanos != heardBefore) { // heard() ran meanwhile and saw nothing to clear
                    quietSince.compareAndSet(since, null);
                } else {
                    quiet.accept(since); // (a heard() from now on clears it and says so)
                }
            }
        }
        ping.run();
    }

    @Override
    public void close() {
        thread.shutdownNow();
    }
}
