"""The CD's colour fringes measured in an image: rim, polar unwrap, band edges, hue, shadow."""
