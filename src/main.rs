fn main() {
    println!("frfbayes: under construction");
}
