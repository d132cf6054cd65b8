fn main() {
    println!("thicket");
}
