package dsagemario;

import engine.core.MarioTimer;

/**
 * A MarioTimer whose remaining "time" is a budget of A* search iterations.
 *
 * <p>Robin Baumgarten's A* agent ({@code agents.robinBaumgarten.AStarTree.search}) calls
 * {@link #getRemainingTime()} exactly once per search iteration and stops when it returns 0.
 * The stock timer measures wall-clock milliseconds, so results depend on machine load; counting
 * calls instead makes every episode repeatable. A fresh timer is created for every agent call,
 * just as the framework's game loop creates a fresh 40 ms timer per tick.
 */
public class DeterministicTimer extends MarioTimer {
    private long remaining;

    public DeterministicTimer(long iterations) {
        super(iterations);
        this.remaining = iterations;
    }

    /** Returns the iterations left, then spends one. */
    @Override
    public long getRemainingTime() {
        long left = remaining;
        if (remaining > 0) {
            remaining--;
        }
        return left;
    }
}
