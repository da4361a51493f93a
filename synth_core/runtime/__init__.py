"""At run time (Sung 2011, sections 5-6): trajectories in, the plan, the render, foot lock, batch
streaming and live sessions."""
